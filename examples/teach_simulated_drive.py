#!/usr/bin/env python3
"""Teach a map on a simulated drive and look inside it.

    PYTHONPATH=build/python python3 examples/teach_simulated_drive.py out/ [--frames 100]

Renders a drive through retrace's procedural town (retrace.Simulator), teaches a map from its frames
(retrace.Teacher, written to out/town.db as `retrace teach` writes maps), prints its nodes and arcs, and saves one
key-image with its features drawn to out/key_image.png.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import retrace  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("out", type=pathlib.Path, help="output folder")
parser.add_argument("--frames", type=int, default=100, help="frames to drive (10 per second, up to 8 m/s)")
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)

# Render and teach frame by frame: each frame comes with its ground-truth pose (world_from_cam, 4x4).
simulator = retrace.Simulator(frames=args.frames, width=320, height=240)
positions = []
with retrace.Teacher(args.out / "town.db", simulator.camera, overwrite=True) as teacher:
    for frame in simulator:
        teacher.add_frame(frame.image, timestamp=frame.timestamp)
        positions.append(frame.world_from_cam[:3, 3])
print(f"{len(positions)} frames, the last {np.linalg.norm(positions[-1] - positions[0]):.1f} m from the first")

route = retrace.Map(args.out / "town.db")
print(route)
for node in route.nodes:
    print(f"  node {node.id}: frame {node.source_frame}, {node.num_features} features, "
          f"{np.linalg.norm(positions[node.source_frame] - positions[0]):.1f} m from the start")
for arc in route.arcs:
    print(f"  arc {arc.id}: {arc.node_from} -> {arc.node_to} ({arc.kind}), {arc.num_features} features, "
          f"sigma_p {arc.sigma_p:.2f} px, median depth {np.median(arc.points[:, 2]):.1f} arc lengths")

# A key-image with its features: those its arc reconstructs in green, the others in red.
arc = route.arcs[len(route.arcs) // 2]
node = route.node(arc.node_from)
mapped = np.isin(node.feature_ids, arc.feature_ids)
plt.figure(figsize=(6.4, 4.8))
plt.imshow(node.image, cmap="gray")
plt.scatter(*node.feature_positions[mapped].T, s=6, color="lime", label=f"in arc {arc.id}")
plt.scatter(*node.feature_positions[~mapped].T, s=6, color="red", label="other features")
plt.legend(loc="lower right")
plt.axis("off")
plt.title(f"key-image {node.id} (frame {node.source_frame})")
plt.savefig(args.out / "key_image.png", dpi=100, bbox_inches="tight")
print(f"wrote {args.out / 'key_image.png'}")
