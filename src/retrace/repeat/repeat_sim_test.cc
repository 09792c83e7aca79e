// Repeat in the simulator, where ground truth is exact (issue acceptance: "repeat drive 1 m to the side of the teach
// drive, different sun, pedestrians crossing: >= 99 % correct, zero wrong by >= 2"): a map is taught on a town drive,
// and the repeat variant of the same scenario (another time of day, 1 m lateral offset with wobble, pedestrians and
// cars elsewhere) is localized in it frame by frame; for the default town and drive and for another one. Ground truth
// decides which arc was right, how far from the taught path the car is (issue 14), and whether the steering command
// (Segvic 2009, eq. (10)) points where the taught path goes.

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/sim/recording.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/statistics.h"

namespace retrace {
namespace {

// The map teach makes of `drive` with the default options.
Map Teach(const RecordedDrive& drive) {
  Teacher teacher(*drive.camera, TeachOptions(), nullptr);
  for (const Frame& frame : drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  return teacher.map();
}

// The scenario's teach drive taught into a map, its repeat variant localized in it frame by frame, and the
// topological evaluation against ground truth.
struct RepeatRun {
  RecordedDrive teach, repeat;
  Map map;
  std::vector<FrameResult> results;
  TopologicalEvaluation evaluation;
};

// Repeats run.repeat on run.map with `options` (results and evaluation replaced).
void Repeat(const LocalizerOptions& options, RepeatRun* run) {
  Localizer localizer(run->map, *run->repeat.camera, options);
  std::vector<RepeatRecord> records;
  run->results.clear();
  for (const Frame& frame : run->repeat.frames) {
    FrameResult result = localizer.ProcessFrame(frame);
    records.push_back({frame.source_index, result.state == LocalizerState::kTracking, result.arc});
    run->results.push_back(std::move(result));
  }
  run->evaluation = EvaluateTopological(run->map, run->teach.truth, run->repeat.truth, records);
}

RepeatRun TeachAndRepeat(const Scenario& scenario, const LocalizerOptions& options) {
  RepeatRun run;
  run.teach = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  run.repeat = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  run.map = Teach(run.teach);
  Repeat(options, &run);
  return run;
}

// Teaches the scenario's drive (200 frames), repeats its repeat variant and checks the acceptance: at least
// 99 % of the frames on the correct arc (±1 near a node), none two or more arcs off, at most 1 % lost; and the
// steering command against ground truth (when the drive turns).
void RepeatAndCheck(const Scenario& base, const std::string& label, bool check_steering) {
  Scenario scenario = base;
  scenario.num_frames = 200;
  LocalizerOptions options;
  options.path.camera_height = scenario.vehicle.camera_height;  // what the robot's owner measures
  const RepeatRun run = TeachAndRepeat(scenario, options);
  const RecordedDrive& teach = run.teach;
  const RecordedDrive& repeat = run.repeat;
  const Map& map = run.map;
  const std::vector<FrameResult>& results = run.results;
  const TopologicalEvaluation& evaluation = run.evaluation;
  ASSERT_EQ(repeat.frames.size(), 200u);
  ASSERT_GE(map.arcs().size(), 10u);
  std::cout << label << " (other sun, 1 m offset, pedestrians), " << map.nodes().size()
            << " key-images: " << evaluation.Summary() << "\n";

  // Never a confident wrong answer: no frame two or more arcs away from the true one.
  EXPECT_EQ(evaluation.wrong_by_two, 0);
  for (size_t i = 0; i < evaluation.per_frame.size(); ++i) {
    const FrameTruth& t = evaluation.per_frame[i];
    if (t.correct) continue;
    const FrameResult& r = results[i];
    std::cout << "  frame " << i << ": " << LocalizerStateName(r.state) << ", arc index " << t.estimated_arc_index
              << ", true " << t.true_arc_index << "; tracked " << r.tracked << " (" << r.tracked_by_role[0] << "/"
              << r.tracked_by_role[1] << "/" << r.tracked_by_role[2] << "), sigma_p " << r.sigma_p_from << "/"
              << r.sigma_p_to << ", pose " << r.position_via_pose << " (sigma_p " << r.sigma_p_pose << ", "
              << r.pose_inliers << " inliers), confidence " << r.confidence << (r.evidence ? "" : " without evidence")
              << ", transition " << r.transition << (r.bootstrapped ? ", bootstrapped" : "") << "\n";
  }
  EXPECT_GE(evaluation.FractionCorrect(), 0.99);
  EXPECT_LE(evaluation.lost, evaluation.frames / 100);

  // The lateral offset from the taught path in metres against ground truth (issue 14 asks a median <= 5 cm and a
  // 95th percentile <= 15 cm). Each frame's own offset (frame_lateral_m) has runs of frames whose pose rests on
  // features at one depth, or on an arc reconstructed a few degrees off; the reported one combines the recent
  // frames (LocalizerOptions::lateral_filter), each with the σ of a pose whose residual noise is floored at the
  // tracker's accuracy, which outvotes runs shorter than half its window: its 95th percentile must be below the
  // frames' own, and its median not above it by more than 200 frames can tell (below). Measured with the arcs' points
  // from their neighbours' key-images too (LocalizerOptions::multi_view_points, the default since 2026-12-07):
  // 0.0187 / 0.082 against 0.0195 / 0.101 m on the first drive, 0.0251 / 0.161 against 0.0243 / 0.188 m on the
  // second (before, with each arc's two key-images only: 0.022 / 0.110 against 0.024 / 0.140 m and 0.026 / 0.197
  // against 0.031 / 0.224 m; over the validation matrix's 19 drives 1 m aside the 95th percentile is lower in all and
  // the median in 14, docs/repeat.md).
  std::vector<double> lateral_errors, frame_lateral_errors, heading_z;
  for (size_t i = 0; i < results.size(); ++i) {
    const FrameResult& r = results[i];
    if (r.state != LocalizerState::kTracking || !r.path.valid) continue;
    const MapArc* arc = map.FindArc(r.arc);
    ASSERT_NE(arc, nullptr);
    const auto previous = map.ArcsTo(arc->from);
    const auto next = map.ArcsFrom(arc->to);
    const int64_t first = map.FindNode(previous.empty() ? arc->from : previous.front()->from)->source_frame;
    const int64_t last = map.FindNode(next.empty() ? arc->to : next.front()->to)->source_frame;
    const PathTruth truth = TruthAgainstTaughtPath(repeat.truth[i].world_from_cam, teach.truth,
                                                   static_cast<size_t>(first), static_cast<size_t>(last));
    if (truth.valid) {
      lateral_errors.push_back(std::abs(r.path.lateral_m - truth.lateral_m));
      frame_lateral_errors.push_back(std::abs(r.path.frame_lateral_m - truth.lateral_m));
      heading_z.push_back(std::abs(r.path.heading_error_rad - truth.heading_error_rad) / r.path.heading_sigma_rad);
    }
  }
  ASSERT_GT(lateral_errors.size(), results.size() / 2);
  const double median = Quantile(lateral_errors, 0.5);
  const double tail = Quantile(lateral_errors, 0.95);
  const double frame_median = Quantile(frame_lateral_errors, 0.5);
  std::cout << "lateral offset against ground truth, " << lateral_errors.size() << " frames: median " << median
            << " m, 95th percentile " << tail << " m (each frame's own: median " << frame_median
            << " m, 95th percentile " << Quantile(frame_lateral_errors, 0.95) << " m)\n";
  EXPECT_LE(median, 0.05);
  EXPECT_LT(tail, Quantile(frame_lateral_errors, 0.95));
  // At the median: the difference of the two medians against its standard error, from a paired moving-block
  // bootstrap (blocks of 10 frames: the frames' errors come in runs) — 0.0018 and 0.0021 m here, more than the
  // differences (-0.0009 and +0.0008 m): on one drive the two medians are a tie, which a strict comparison decided
  // by chance.
  const double median_difference_se = PairedMedianDifferenceStandardError(lateral_errors, frame_lateral_errors, 10);
  std::cout << "  combined minus own median " << median - frame_median << " m, standard error " << median_difference_se
            << " m\n";
  EXPECT_LT(median - frame_median, 2.0 * median_difference_se);
  // The heading error's σ (the path's direction and the pose's rotation) is of the size of the errors: a Gaussian's
  // |error| / σ has a median of 0.67. Here 1.05 on the first drive and 0.80 on the second, the travel model's
  // direction with its own σ from the spread of the arcs it was fitted to (TravelModel::DirectionSigma) and the
  // rotation's with the pose's residual noise floored (0.60 and 0.27 with the constant TaughtPathOptions::
  // travel_sigma_rad, five times the simulated maps' errors; docs/path-tracking.md, "The heading's σ from the map").
  const double heading_z_median = Quantile(heading_z, 0.5);
  std::cout << "heading error / its sigma: median " << heading_z_median << "\n";
  EXPECT_GT(heading_z_median, 0.3);
  EXPECT_LT(heading_z_median, 2.0);

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
  if (!check_steering) return;
  ASSERT_GT(checked, 40);
  EXPECT_GE(agreeing, 0.85 * checked);
}

TEST(RepeatSim, OtherSunOffsetAndPedestrians) {
  // The town and drive of `retrace sim example-scenario` and the demo; its first 200 frames take three turns.
  RepeatAndCheck(Scenario(), "default town and drive", /*check_steering=*/true);
}

TEST(RepeatSim, AnotherTownAndRoute) {
  // A town and a route the defaults were not tuned on (seed 2 of both); its first 200 frames go straight on.
  Scenario scenario;
  scenario.seed = 2;
  scenario.town.seed = 2;
  RepeatAndCheck(scenario, "town and drive of seed 2", /*check_steering=*/false);
}

// The localizer keeps the derived data (pyramids, references, key-points) of a bounded number of key-images, so a
// drive of any length runs in flat memory; releasing it must change nothing but memory. The repeat drive is run
// twice in a row (the second lap starts with a relocalization at the route's start) with room for 3 key-images and
// for all of them: the same state, arc and position in every frame, and never more than 3 key-images held.
TEST(RepeatSim, BoundedKeyImageCacheChangesNothingButMemory) {
  Scenario scenario;
  scenario.num_frames = 80;
  const RecordedDrive teach = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  const RecordedDrive repeat = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  const Map map = Teach(teach);
  ASSERT_GE(map.nodes().size(), 8u);

  LocalizerOptions bounded_options;
  bounded_options.max_cached_key_images = 3;
  LocalizerOptions unbounded_options;
  unbounded_options.max_cached_key_images = static_cast<int>(map.nodes().size());
  Localizer bounded(map, *repeat.camera, bounded_options);
  Localizer unbounded(map, *repeat.camera, unbounded_options);
  int largest_unbounded = 0, tracking = 0;
  for (int lap = 0; lap < 2; ++lap) {
    for (const Frame& frame : repeat.frames) {
      const FrameResult a = bounded.ProcessFrame(frame);
      const FrameResult b = unbounded.ProcessFrame(frame);
      ASSERT_EQ(a.state, b.state) << "lap " << lap << " frame " << frame.index;
      ASSERT_EQ(a.arc, b.arc) << "lap " << lap << " frame " << frame.index;
      ASSERT_EQ(a.position_on_arc, b.position_on_arc) << "lap " << lap << " frame " << frame.index;
      ASSERT_EQ(a.tracked, b.tracked) << "lap " << lap << " frame " << frame.index;
      ASSERT_LE(bounded.NumCachedKeyImages(), 3);
      largest_unbounded = std::max(largest_unbounded, unbounded.NumCachedKeyImages());
      tracking += a.state == LocalizerState::kTracking;
    }
  }
  // The bound was exercised: unbounded, the localizer held many more key-images.
  EXPECT_GE(largest_unbounded, 8);
  EXPECT_GE(tracking, 140);
}

// Kidnapped starts (issue 16): a fresh localizer without a start arc at 20 frames of the repeat drive, the whole map
// ranked by appearance and visual words fused (the default) and by appearance alone. Never a wrong place, and the
// words find the place at the first frame at least as often. The map's words are built once (as LoadMapForLocalizer
// does) and shared by every localizer given a copy of it.
TEST(RepeatSim, KidnappedStartsRankedByAppearanceAndVisualWords) {
  Scenario scenario;
  scenario.num_frames = 200;
  const RecordedDrive teach = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  const RecordedDrive repeat = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  const Map taught = Teach(teach);
  Map map = taught;
  LocalizerOptions options;
  map.SetVisualWords(Localizer::BuildMapVisualWords(map, options));
  ASSERT_NE(map.visual_words(), nullptr);
  EXPECT_EQ(map.visual_words()->index.size(), map.nodes().size());
  EXPECT_GE(map.visual_words()->vocabulary.size(), 100);

  std::array<int, 2> localized{}, wrong{};
  for (const bool words : {true, false}) {
    options.visual_word_retrieval = words;
    std::vector<RepeatRecord> records;
    for (size_t start = 5; start < repeat.frames.size(); start += 10) {
      Localizer localizer(map, *repeat.camera, options);
      const FrameResult result = localizer.ProcessFrame(repeat.frames[start]);
      records.push_back({repeat.frames[start].source_index, result.state == LocalizerState::kTracking, result.arc});
    }
    const TopologicalEvaluation evaluation = EvaluateTopological(map, teach.truth, repeat.truth, records);
    for (const FrameTruth& t : evaluation.per_frame) {
      localized[words] += t.correct;
      wrong[words] += !t.lost && !t.correct;
    }
  }
  std::cout << "kidnapped starts localized at the first frame: " << localized[1] << " of 20 with visual words, "
            << localized[0] << " by appearance alone\n";
  EXPECT_EQ(wrong[1], 0);
  EXPECT_EQ(wrong[0], 0);
  EXPECT_GE(localized[1], localized[0]);
  EXPECT_GE(localized[1], 17);
  // Retrieval by words off: a localizer given a map without words builds none.
  options.visual_word_retrieval = false;
  EXPECT_EQ(Localizer(taught, *repeat.camera, options).map().visual_words(), nullptr);
  // A map changed after its words were built drops them.
  map.MutableNode(map.nodes().front().id);
  EXPECT_EQ(map.visual_words(), nullptr);
}

// A lane's width beside the taught drive (issue 13: "zero frames on a wrong arc by >= 2 anywhere"; >= 95 % correct
// at 2.5 m). The default drive repeated 2.5 m to the right under the other sun: most mapped features no longer align
// with references cut 2.5 m away, so a fifth of the frames are honestly lost (the 95 % target is missed here, 81.0 %
// when this test was written; printed, not checked). What is checked is that no frame is reported on a wrong arc:
// right after the first bootstrap the absolute pose rested on six features found one texture period off (five of
// them within 20 pixels) and placed the camera 2.3 arcs ahead, hovering 0.65 arc lengths above the road; the
// belief took it for three frames, the third two arcs off. The height check of the pose
// (PlacementModel::pose_height_sigma) takes such a pose for an outlier.
TEST(RepeatSim, TwoAndAHalfMetresBesideNoFrameOnAWrongArc) {
  Scenario scenario;
  scenario.num_frames = 200;
  scenario.repeat.lateral_offset = 2.5;
  // Without the camera's height (the ground's normal, which the check needs, comes from the map alone); first with
  // the paper's warp alone, the three the localizer has on by default off (README, "The three as the default").
  const LocalizerOptions paper = LocalizerOptions().WithPaperWarp();
  RepeatRun run = TeachAndRepeat(scenario, paper);
  const TopologicalEvaluation evaluation = run.evaluation;
  std::cout << "default town and drive 2.5 m aside, " << run.map.nodes().size()
            << " key-images: " << evaluation.Summary() << "\n";
  EXPECT_EQ(evaluation.wrong_by_two, 0);
  EXPECT_EQ(evaluation.wrong, 0);
  // Not a town where nothing localizes: most frames are tracked.
  EXPECT_GT(evaluation.FractionCorrect(), 0.5);

  // Guided matching near a loss (LocalizerOptions::guided_matching_min_inliers) verifies the key-images beside the
  // path that the ratio-tested matches alone do not (81.0 -> 86.5 % correct here when written, one frame one arc off),
  // and none two arcs off.
  LocalizerOptions guided = paper;
  guided.guided_matching_min_inliers = 20;
  Repeat(guided, &run);
  std::cout << "  with guided matching: " << run.evaluation.Summary() << "\n";
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  EXPECT_GT(run.evaluation.correct, evaluation.correct + 5);

  // Tracks refined with an affine warp (LocalizerOptions::affine_refinement) and placed features started fine
  // (FeatureTrackerOptions::placed_features_start_fine): beside the path the key-images' windows are sheared in the
  // current view, and the paper's warp aligns them at shifted centres (82.0 -> 89.0 % correct here when written,
  // one frame one arc off), none two arcs off.
  LocalizerOptions refined = paper;
  refined.affine_refinement = true;
  refined.tracker.placed_features_start_fine = true;
  Repeat(refined, &run);
  std::cout << "  with the tracks refined by an affine warp: " << run.evaluation.Summary() << "\n";
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  EXPECT_GT(run.evaluation.correct, evaluation.correct + 10);
  const int refined_correct = run.evaluation.correct;

  // The three together: at least as many frames correct as the refinement alone (91.5 % against 89.0 % when
  // written).
  LocalizerOptions three;
  three.place_by_verified_key_images = false;
  Repeat(three, &run);
  std::cout << "  with the three: " << run.evaluation.Summary() << "\n";
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  EXPECT_GT(run.evaluation.correct, evaluation.correct + 10);
  EXPECT_GE(run.evaluation.correct, refined_correct);
  const int three_correct = run.evaluation.correct;

  // The default also places the camera by the key-images a relocalization verified when too few mapped features align
  // through them (LocalizerOptions::place_by_verified_key_images): more frames correct (89.5 -> 90.5 % when written:
  // the belief kept on the place while relocalizing), none on a wrong arc, and any frame reported tracking with no
  // feature tracked on the correct arc (without the check of its own placement's support, PlaceBelief::
  // MeasurementSupport, frame 12 was so reported one arc ahead).
  Repeat(LocalizerOptions(), &run);
  std::cout << "  with the defaults (the three, and placed by the verified key-images): " << run.evaluation.Summary()
            << "\n";
  EXPECT_EQ(run.evaluation.wrong, 0);
  EXPECT_GT(run.evaluation.correct, three_correct);
  int placed_alone = 0;
  for (size_t i = 0; i < run.results.size(); ++i) {
    if (run.results[i].state != LocalizerState::kTracking || run.results[i].tracked > 0) continue;
    ++placed_alone;
    EXPECT_TRUE(run.evaluation.per_frame[i].correct) << "frame " << i;
  }
  std::cout << "  frames tracking with no feature tracked: " << placed_alone << "\n";

  // With robust relocalization (LocalizerOptions::relocalization_robust_alignment), which after a loss also locates
  // the mapped features whose windows straddle two surfaces the other sun lit differently and tracks them on: more
  // frames correct when written (89.5 -> 92.5 %); since a current geometry far beside its key-image counts as the
  // outlier it mostly is (PlacementModel::geometry_distance_length, 2026-12-08) as many as the three here (90.5 %),
  // none two arcs off.
  LocalizerOptions robust = three;
  robust.relocalization_robust_alignment = true;
  Repeat(robust, &run);
  std::cout << "  with robust relocalization: " << run.evaluation.Summary() << "\n";
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  EXPECT_GE(run.evaluation.correct, three_correct);

  // Robots set down 2.5 m beside the path (a fresh localizer at every 5th frame, no start arc): the mapped features
  // a start locates through its verified key-images are seen sheared, and the matches around each lie at other
  // depths. Located three ways: from the median displacement of the matches around each alone; the default, which
  // aligns a feature that fails so from the nearest matches in turn (LocalizerOptions::start_alternative_starts);
  // and from the median with the affine fallback (relocalization_affine_fallback: 981 -> 1168 over the starts both
  // localized when written, 31 -> 32 of 40 starts localized). None on a wrong arc in any, and both others localize at
  // least as many starts and locate more features over the starts all three localize: the affine fallback a tenth more,
  // the nearest matches a twentieth (when written: 31 / 33 / 32 starts, 970 / 1076 / 1169 features).
  LocalizerOptions median_alone;
  median_alone.start_alternative_starts = 0;
  LocalizerOptions affine = median_alone;
  affine.relocalization_affine_fallback = true;
  const std::array<LocalizerOptions, 3> ways{median_alone, LocalizerOptions(), affine};
  std::array<std::vector<FrameResult>, 3> first_frames;
  std::array<TopologicalEvaluation, 3> starts;
  for (size_t way = 0; way < ways.size(); ++way) {
    std::vector<RepeatRecord> records;
    for (size_t start = 2; start < run.repeat.frames.size(); start += 5) {
      Localizer localizer(run.map, *run.repeat.camera, ways[way]);
      first_frames[way].push_back(localizer.ProcessFrame(run.repeat.frames[start]));
      const FrameResult& result = first_frames[way].back();
      records.push_back({run.repeat.frames[start].source_index, result.state == LocalizerState::kTracking, result.arc});
    }
    starts[way] = EvaluateTopological(run.map, run.teach.truth, run.repeat.truth, records);
  }
  std::array<int, 3> located{};
  for (size_t i = 0; i < first_frames[0].size(); ++i) {
    if (!starts[0].per_frame[i].correct || !starts[1].per_frame[i].correct || !starts[2].per_frame[i].correct) {
      continue;
    }
    for (size_t way = 0; way < ways.size(); ++way) located[way] += first_frames[way][i].tracked;
  }
  std::cout << "  kidnapped starts 2.5 m beside localized at the first frame: " << starts[0].correct << " of "
            << starts[0].frames << " from the median alone, " << starts[1].correct << " also from the nearest matches, "
            << starts[2].correct << " with the affine fallback; features located in the starts all localized "
            << located[0] << " / " << located[1] << " / " << located[2] << "\n";
  for (size_t way = 0; way < ways.size(); ++way) EXPECT_EQ(starts[way].wrong, 0) << "way " << way;
  for (const size_t way : {1, 2}) EXPECT_GE(starts[way].correct, starts[0].correct) << "way " << way;
  EXPECT_GT(located[1], located[0] + located[0] / 20);
  EXPECT_GT(located[2], located[0] + located[0] / 10);

  // Robust relocalization is not used at a start (with it, the start at frame 2 was placed two arcs ahead when
  // written): every start as by default.
  for (size_t start = 2, i = 0; start < run.repeat.frames.size(); start += 5, ++i) {
    Localizer localizer(run.map, *run.repeat.camera, robust);
    const FrameResult result = localizer.ProcessFrame(run.repeat.frames[start]);
    EXPECT_EQ(result.state, first_frames[1][i].state) << "frame " << start;
    EXPECT_EQ(result.arc, first_frames[1][i].arc) << "frame " << start;
    EXPECT_EQ(result.tracked, first_frames[1][i].tracked) << "frame " << start;
  }
}

}  // namespace
}  // namespace retrace
