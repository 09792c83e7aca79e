// Repeat in the simulator, where ground truth is exact (issue acceptance: "repeat drive 1 m to the side of the teach
// drive, different sun, pedestrians crossing"): a map is taught on the default town drive, and the repeat variant of
// the same scenario (another time of day, 1 m lateral offset with wobble, pedestrians and cars elsewhere) is
// localized in it frame by frame. Ground truth decides which arc was right and whether the steering command
// (Segvic 2009, eq. (10)) points where the taught path goes.

#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/sim/simulator.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

struct Drive {
  std::unique_ptr<CameraModel> camera;
  std::vector<Frame> frames;
  std::vector<TimedPose> truth;
};

Drive Record(const Scenario& scenario) {
  Simulator simulator(scenario);
  Drive drive;
  drive.camera = simulator.camera().Clone();
  SimFrame sim_frame;
  while (simulator.NextFrame(&sim_frame)) {
    Frame frame;
    frame.index = frame.source_index = drive.frames.size();
    frame.name = std::to_string(frame.index) + ".png";
    frame.timestamp = sim_frame.timestamp;
    frame.image = sim_frame.image;
    drive.frames.push_back(frame);
    drive.truth.push_back({sim_frame.timestamp, sim_frame.world_from_cam});
  }
  return drive;
}

TEST(RepeatSim, OtherSunOffsetAndPedestrians) {
  Scenario scenario;  // the default town and drive of `retrace sim example-scenario` and the demo
  scenario.num_frames = 200;
  const Drive teach = Record(ApplyVariant(scenario, ScenarioVariant::kTeach));
  const Drive repeat = Record(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  ASSERT_EQ(repeat.frames.size(), 200u);

  Teacher teacher(*teach.camera, TeachOptions(), nullptr);
  for (const Frame& frame : teach.frames) teacher.AddFrame(frame);
  teacher.Finish();
  const Map& map = teacher.map();
  ASSERT_GE(map.arcs().size(), 10u);

  Localizer localizer(map, *repeat.camera);
  std::vector<RepeatRecord> records;
  std::vector<FrameResult> results;
  for (const Frame& frame : repeat.frames) {
    FrameResult result = localizer.ProcessFrame(frame);
    records.push_back({frame.source_index, result.state == LocalizerState::kTracking, result.arc});
    results.push_back(std::move(result));
  }
  const TopologicalEvaluation evaluation = EvaluateTopological(map, teach.truth, repeat.truth, records);
  std::cout << "simulated repeat (other sun, 1 m offset, pedestrians): " << evaluation.Summary() << "\n";

  // Never a confident wrong answer: no frame two or more arcs away from the true one.
  EXPECT_EQ(evaluation.wrong_by_two, 0);
  // The target is 99 % correct, which is NOT met: measured 90.5 % correct and 9.5 % lost on these 200
  // frames (README). This guards the measured level against regressions.
  EXPECT_GE(evaluation.FractionCorrect(), 0.85);
  EXPECT_LE(evaluation.wrong, evaluation.frames / 20);

  // Steering (eq. (10)) against ground truth: when the next key-image lies clearly to one side of the current
  // camera (> 3 degrees), the command turns towards it (negative = left, as x grows to the right).
  int checked = 0, agreeing = 0;
  for (size_t i = 0; i < results.size(); ++i) {
    const FrameResult& r = results[i];
    if (r.state != LocalizerState::kTracking || !r.steering_valid) continue;
    const MapNode* node = map.FindNode(r.node_to);
    ASSERT_NE(node, nullptr);
    const Rigid3d cam_from_world = repeat.truth[i].world_from_cam.Inverse();
    const Vector3d target = cam_from_world * teach.truth[node->source_frame].world_from_cam.translation;
    const double bearing = std::atan2(target.x(), target.z());
    if (std::abs(bearing) < 3.0 * M_PI / 180.0) continue;
    ++checked;
    agreeing += (r.steering < 0) == (bearing < 0);
  }
  std::cout << "steering sign agrees with the bearing of the next key-image in " << agreeing << " of " << checked
            << " frames\n";
  ASSERT_GT(checked, 50);
  EXPECT_GE(agreeing, 0.75 * checked);
}

}  // namespace
}  // namespace retrace
