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
#include "retrace/sim/recording.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

TEST(RepeatSim, OtherSunOffsetAndPedestrians) {
  Scenario scenario;  // the default town and drive of `retrace sim example-scenario` and the demo
  scenario.num_frames = 200;
  const RecordedDrive teach = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  const RecordedDrive repeat = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kRepeat));
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
  for (size_t i = 0; i < evaluation.per_frame.size(); ++i) {
    const FrameTruth& t = evaluation.per_frame[i];
    if (t.error < 2) continue;
    const FrameResult& r = results[i];
    ADD_FAILURE() << "frame " << i << ": arc index " << t.estimated_arc_index << ", true " << t.true_arc_index
                  << "; tracked " << r.tracked << " (" << r.tracked_by_role[0] << "/" << r.tracked_by_role[1] << "/"
                  << r.tracked_by_role[2] << "), sigma_p " << r.sigma_p_from << "/" << r.sigma_p_to << ", position "
                  << r.position_on_arc << ", transition " << r.transition << (r.bootstrapped ? ", bootstrapped" : "");
  }
  // The target is 99 % correct, which is NOT met: measured 96.5 % correct and 3.5 % one arc off (a
  // transition a frame or two early or late; arcs are ~6 frames long here), none lost, on these 200 frames
  // (README). This guards the measured level against regressions.
  EXPECT_GE(evaluation.FractionCorrect(), 0.95);
  EXPECT_LE(evaluation.lost, evaluation.frames / 50);
  EXPECT_LE(evaluation.wrong, evaluation.frames / 20);

  // Steering (eq. (10)) against ground truth. The mapped features are mostly distant, for which x_t - x* is the
  // heading difference between the current camera and the next key-image: when the next key-image looks more than
  // 2 degrees to one side of where the camera looks, the command must turn that way (negative = left, as x grows
  // to the right).
  int checked = 0, agreeing = 0;
  for (size_t i = 0; i < results.size(); ++i) {
    const FrameResult& r = results[i];
    if (r.state != LocalizerState::kTracking || !r.steering_valid) continue;
    const MapNode* node = map.FindNode(r.node_to);
    ASSERT_NE(node, nullptr);
    const Matrix3d current_from_key =
        repeat.truth[i].world_from_cam.rotation.transpose() * teach.truth[node->source_frame].world_from_cam.rotation;
    const Vector3d key_forward = current_from_key.col(2);  // the key-image's optical axis in the current camera
    const double yaw = std::atan2(key_forward.x(), key_forward.z());
    if (std::abs(yaw) < 2.0 * M_PI / 180.0) continue;
    ++checked;
    agreeing += (r.steering < 0) == (yaw < 0);
  }
  std::cout << "steering turns towards the next key-image's heading in " << agreeing << " of " << checked
            << " frames (heading difference > 2 degrees)\n";
  ASSERT_GT(checked, 40);
  EXPECT_GE(agreeing, 0.85 * checked);
}

}  // namespace
}  // namespace retrace
