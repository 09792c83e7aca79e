#!/usr/bin/python3
"""Helpers of node_test.sh (Debian's /usr/bin/python3, which has rospy).

  node_test.py listen OUT.json NODE[,NODE...] FRAMES LAST_STAMP TIMEOUT
      Records cmd_vel, <node>/state and /diagnostics until every node has published FRAMES states or one whose
      stamp is LAST_STAMP (the bag's last frame), or TIMEOUT seconds passed; writes what it received as JSON.
  node_test.py compare OUT.json REPEAT.csv SPEED
      Checks the first node's states and cmd_vel against `retrace repeat`'s CSV of the same frames, and that the
      second node (newest frame only) dropped stale frames and still processed the last one.
"""

import csv
import json
import sys
import time


def listen(out_path, nodes, frames, last_stamp, timeout):
    import rospy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import Twist
    from std_msgs.msg import String

    received = {node: {"states": [], "cmd_vel": []} for node in nodes}
    diagnostics = []

    def on_state(node):
        return lambda message: received[node]["states"].append(json.loads(message.data))

    def on_cmd_vel(node):
        return lambda message: received[node]["cmd_vel"].append([message.linear.x, message.angular.z])

    rospy.init_node("retrace_node_test_listener", disable_signals=True)
    subscribers = []
    for node in nodes:
        subscribers.append(rospy.Subscriber(f"/{node}/state", String, on_state(node), queue_size=10000))
        subscribers.append(rospy.Subscriber(f"/{node}/cmd_vel", Twist, on_cmd_vel(node), queue_size=10000))
    subscribers.append(rospy.Subscriber("/diagnostics", DiagnosticArray,
                                        lambda m: diagnostics.extend(
                                            {"name": s.name, "level": ord(s.level) if isinstance(s.level, bytes)
                                             else int(s.level), "message": s.message,
                                             "values": {v.key: v.value for v in s.values}} for s in m.status),
                                        queue_size=1000))
    # Every subscription connected to its publisher before the bag plays (the nodes advertise before "ready").
    deadline = time.time() + 60
    while time.time() < deadline and not all(s.get_num_connections() > 0 for s in subscribers):
        time.sleep(0.1)
    print("listening" if all(s.get_num_connections() > 0 for s in subscribers) else "not connected", flush=True)

    def done(node):
        states = received[node]["states"]
        return len(states) >= frames or (states and abs(states[-1]["stamp"] - last_stamp) < 1e-6)

    deadline = time.time() + timeout
    while time.time() < deadline and not all(done(n) for n in nodes):
        time.sleep(0.1)
    time.sleep(0.5)  # the last cmd_vel and diagnostics of the last frame
    with open(out_path, "w") as out:
        json.dump({"nodes": received, "diagnostics": diagnostics}, out)
    rospy.signal_shutdown("done")


def compare(out_path, csv_path, speed):
    with open(out_path) as f:
        recorded = json.load(f)
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    nodes = list(recorded["nodes"])
    failures = []

    def check(condition, message):
        if not condition:
            failures.append(message)

    # The node processing every frame: the same states, arcs and steering as `retrace repeat`, frame by frame.
    every = recorded["nodes"][nodes[0]]
    states, cmd_vel = every["states"], every["cmd_vel"]
    check(len(states) == len(rows), f"{nodes[0]}: {len(states)} states for {len(rows)} frames")
    check(len(cmd_vel) == len(states), f"{nodes[0]}: {len(cmd_vel)} cmd_vel for {len(states)} states")
    worst_steering = 0.0
    for i, (state, row) in enumerate(zip(states, rows)):
        where = f"{nodes[0]} frame {i}"
        check(state["frame"] == int(row["frame"]), f"{where}: frame index {state['frame']}")
        check(abs(state["stamp"] - float(row["timestamp"])) < 1e-5,
              f"{where}: stamp {state['stamp']} vs {row['timestamp']}")
        check(state["state"] == row["state"], f"{where}: state {state['state']} vs {row['state']}")
        check(state["arc"] == int(row["arc"]), f"{where}: arc {state['arc']} vs {row['arc']}")
        check(state["node_from"] == int(row["node_from"]) and state["node_to"] == int(row["node_to"]),
              f"{where}: nodes {state['node_from']}->{state['node_to']} vs {row['node_from']}->{row['node_to']}")
        check(abs(state["confidence"] - float(row["confidence"])) < 1e-4,
              f"{where}: confidence {state['confidence']} vs {row['confidence']}")
        steering = state["steering"] if state["steering"] is not None else 0.0
        worst_steering = max(worst_steering, abs(steering - float(row["steering"])))
        check(abs(steering - float(row["steering"])) < 1e-4, f"{where}: steering {steering} vs {row['steering']}")
        check(state["dropped"] == 0, f"{where}: {state['dropped']} frames dropped")
        if i < len(cmd_vel):
            linear, angular = cmd_vel[i]
            tracking = row["state"] == "tracking"
            check(abs(linear - (speed if tracking else 0.0)) < 1e-9, f"{where}: linear.x {linear}")
            # REP 103: positive angular.z turns left; eq. (10)'s w < 0 turns left.
            check(abs(angular - (-steering if tracking else 0.0)) < 1e-9, f"{where}: angular.z {angular}")
    tracking = sum(r["state"] == "tracking" for r in rows)
    check(0 < tracking < len(rows), f"{tracking} of {len(rows)} repeat frames tracking: the drive should have both "
                                    "tracking and lost frames")

    # The node keeping up with the camera: it dropped stale frames, and processed the bag's last frame.
    live = recorded["nodes"][nodes[1]]["states"] if len(nodes) > 1 else None
    if live is not None:
        check(0 < len(live) < len(rows), f"{nodes[1]}: {len(live)} of {len(rows)} frames processed (expected drops)")
        check(live and live[-1]["dropped"] > 0, f"{nodes[1]}: no frame dropped")
        check(live and abs(live[-1]["stamp"] - float(rows[-1]["timestamp"])) < 1e-5,
              f"{nodes[1]}: the last frame was not processed")
        check(all(a["stamp"] < b["stamp"] for a, b in zip(live, live[1:])), f"{nodes[1]}: frames out of order")

    diagnostics = [d for d in recorded["diagnostics"] if d["name"] == f"/{nodes[0]}: repeat"]
    check(len(diagnostics) > 0, "no /diagnostics from the node")
    check(any(d["level"] == 0 and d["values"].get("state") == "tracking" for d in diagnostics),
          "no OK diagnostics while tracking")

    for message in failures[:20]:
        print("FAIL", message)
    live_text = f", {nodes[1]}: {len(live)} processed, {live[-1]['dropped']} dropped" if live else ""
    print(f"{nodes[0]}: {len(states)} frames ({tracking} tracking in repeat), largest steering difference "
          f"{worst_steering:.2e}{live_text}; {len(diagnostics)} diagnostics; {len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    if sys.argv[1] == "listen":
        listen(sys.argv[2], sys.argv[3].split(","), int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]))
    elif sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3], float(sys.argv[4])))
    else:
        sys.exit(f"unknown command {sys.argv[1]}")
