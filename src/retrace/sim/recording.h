#pragma once

// Recording a simulated drive to disk in the KITTI odometry layout, so every other tool reads simulated and real
// sequences the same way:
// (written by dataset/KittiSequenceWriter):
//   DIR/image_0/000000.png ...   the frames (grey, or colour when sensor.color)
//   DIR/times.txt                one timestamp (s) per line
//   DIR/poses.txt                ground truth: world_from_cam as 12 numbers (3x4 row-major) per line
//   DIR/calib.txt                "P0: ..." projection matrix K [I | 0] (perspective cameras)
//   DIR/camera.yaml              the full camera model (camera/camera_io.h WriteCameraFile: distortion, panoramas)
//   DIR/scenario.yaml            the effective scenario (after the variant's overrides), to reproduce the run
// The world frame is the simulator's (simulator.h): a level camera on the ground at the route's start.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/sim/simulator.h"

namespace retrace {

struct RecordOptions {
  // Draw a progress bar on stderr.
  bool progress = true;
  // Write a contact sheet (every `contact_sheet_every`-th frame, labelled) to this PNG; empty = none.
  std::filesystem::path contact_sheet;
  int contact_sheet_every = 10;
  int contact_sheet_columns = 4;
};

struct RecordSummary {
  int frames = 0;
  // The scenario's frame count (0 = the whole route) and whether the route ended before it: then `frames` is the
  // number of frames up to the route's end, fewer than asked for.
  int frames_requested = 0;
  bool stopped_at_route_end = false;
  double route_length_m = 0.0;
  double driven_m = 0.0;
  double seconds = 0.0;  // wall-clock time of rendering and writing
};

// Drives the simulator's autopilot to the end of the route or the scenario's frame count, whichever comes first, and
// writes the sequence into `out_dir` (created if needed). Throws InputError when the folder cannot be written.
RecordSummary RecordSequence(Simulator* simulator, const std::filesystem::path& out_dir,
                             const RecordOptions& options);

// Renders the world at given camera poses (world_from_cam in the simulator's world frame, simulator.h; the moving
// occluders at each pose's timestamp) and writes them as a sequence like RecordSequence: for experiments at chosen
// places, e.g. Booij 2007 §B.5.1's grid of positions and orientations. `driven_m` of the summary is the length of the
// polyline through the poses. Throws InputError when the folder cannot be written.
RecordSummary RecordPoses(Simulator* simulator, const std::vector<TimedPose>& poses,
                          const std::filesystem::path& out_dir, const RecordOptions& options);

// A drive recorded in memory (tests, benchmarks): the frames as a Sequence of the written folder gives them
// (index = source_index = frame number, name NNNNNN.png) and their ground-truth poses (world_from_cam, as in
// poses.txt).
struct RecordedDrive {
  std::unique_ptr<CameraModel> camera;
  std::vector<Frame> frames;
  std::vector<TimedPose> truth;
};
RecordedDrive RecordDrive(const Scenario& scenario);

}  // namespace retrace
