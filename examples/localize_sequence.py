#!/usr/bin/env python3
"""Localize a sequence of images in a taught map, frame by frame, and plot the state and the arc over time.

    PYTHONPATH=build/python python3 examples/localize_sequence.py route.db drive/ localization.png

`drive/` is anything `retrace repeat --sequence` reads: a folder of images, a video, a KITTI or EuRoC layout (e.g. a
drive rendered by `retrace sim render --variant repeat`). Writes the plot to the PNG given.
"""

import argparse

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402

import retrace  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("map", help="map file written by `retrace teach` or retrace.Teacher")
parser.add_argument("sequence", help="images to localize (folder, video, KITTI or EuRoC layout)")
parser.add_argument("plot", help="PNG file to write")
args = parser.parse_args()

localizer = retrace.Localizer(args.map)
results = [localizer.process(frame) for frame in retrace.Sequence(args.sequence)]
tracking = [r for r in results if r.state == "tracking"]
print(f"{len(results)} frames: {len(tracking)} tracking, {len(results) - len(tracking)} lost or relocalizing; "
      f"arcs {tracking[0].arc if tracking else '-'} to {tracking[-1].arc if tracking else '-'}")

states = ["lost", "relocalizing", "tracking"]
figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9, 5), height_ratios=[1, 2])
top.plot([r.frame_index for r in results], [states.index(r.state) for r in results], drawstyle="steps-mid")
top.set_yticks(range(len(states)), states)
top.set_title(f"{args.sequence} in {args.map}")
bottom.scatter([r.frame_index for r in tracking], [r.arc for r in tracking], s=8, label="tracking: arc")
bottom.scatter([r.frame_index for r in results if r.state != "tracking"],
               [r.belief_arc for r in results if r.state != "tracking"], s=8, marker="x", color="tab:red",
               label="lost or relocalizing: the belief's most likely arc")
bottom.set_xlabel("frame")
bottom.set_ylabel("arc")
bottom.legend(loc="upper left")
figure.tight_layout()
figure.savefig(args.plot, dpi=100)
print(f"wrote {args.plot}")
