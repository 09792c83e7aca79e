#include "retrace/repeat/belief.h"

#include <cmath>
#include <utility>

#include <gtest/gtest.h>

#include "retrace/repeat/linear_map_testing.h"

namespace retrace {
namespace {

PlaceMeasurement Pose(arc_t arc, double along, double sigma = 0.03) { return {arc, along, sigma, 0.02}; }

// Feeds one frame: motion, then the measurements.
void Frame(PlaceBelief* belief, size_t frame, const std::vector<PlaceMeasurement>& measurements) {
  belief->Predict(1);
  belief->Update(measurements, frame);
}

TEST(PlaceBelief, LengthsFollowTheStoredScalesElseTheTeachFrames) {
  Map map = LinearMap(3, {2.0});
  // Arc 2's key-image is 30 frames after node 2 (three times arc 1's 10 frames) and node 2 stores no scale.
  map.MutableNode(3)->source_frame = 50;
  const PlaceBelief belief(map);
  EXPECT_DOUBLE_EQ(belief.ArcLength(0), 1.0);
  EXPECT_DOUBLE_EQ(belief.ArcLength(1), 2.0);
  EXPECT_DOUBLE_EQ(belief.ArcLength(2), 6.0);
  ASSERT_TRUE(belief.Distance({0, 0.5}, {2, 0.5}, 3).has_value());
  EXPECT_DOUBLE_EQ(*belief.Distance({0, 0.5}, {2, 0.5}, 3), 0.5 + 2.0 + 3.0);
  EXPECT_DOUBLE_EQ(*belief.Distance({2, 0.5}, {0, 0.5}, 3), -5.5);
  EXPECT_FALSE(belief.Distance({0, 0.5}, {2, 0.5}, 1).has_value());
}

TEST(PlaceBelief, ConsistentPlacementsConcentrateItIntoTracking) {
  PlaceBelief belief(LinearMap(10));
  // Before any evidence: uniform, not tracking.
  EXPECT_FALSE(belief.estimate().tracking);
  EXPECT_LT(belief.estimate().confidence, 0.2);
  for (int t = 0; t < 4; ++t) Frame(&belief, t + 1, {Pose(4, 0.2 + 0.1 * t)});
  const PlaceEstimate& estimate = belief.estimate();
  EXPECT_TRUE(estimate.tracking);
  EXPECT_EQ(estimate.arc, 4);
  EXPECT_GT(estimate.confidence, 0.99);
  EXPECT_NEAR(estimate.along, 0.5, 0.05);
  ASSERT_TRUE(belief.SpeedOn(4).has_value());
  EXPECT_NEAR(*belief.SpeedOn(4), 0.1, 0.03);
}

TEST(PlaceBelief, WithoutEvidenceItSpreadsAndIsNotTracking) {
  PlaceBelief belief(LinearMap(40));
  for (int t = 0; t < 4; ++t) Frame(&belief, t + 1, {Pose(4, 0.2 + 0.25 * t)});
  ASSERT_TRUE(belief.estimate().tracking);
  // Frames without a placement: the prediction moves on at the speed (a quarter arc per frame) but the frame has
  // no evidence of its own, so it is not `tracking`.
  for (int t = 4; t < 8; ++t) {
    Frame(&belief, t + 1, {});
    EXPECT_FALSE(belief.estimate().evidence);
    EXPECT_FALSE(belief.estimate().tracking);
  }
  // 0.95 + 4 x 0.25 = 1.95 arcs past arc 4's start: near node 6.
  const std::optional<double> moved = belief.Distance({4, 0.0}, {belief.estimate().arc, belief.estimate().along}, 3);
  ASSERT_TRUE(moved.has_value());
  EXPECT_NEAR(*moved, 1.95, 0.15);
  // Much later, the speed is forgotten and the mass is spread over many arcs: the confidence drops.
  for (int t = 8; t < 20; ++t) Frame(&belief, t + 1, {});
  EXPECT_FALSE(belief.SpeedOn(5).has_value());
  EXPECT_LT(belief.estimate().confidence, 0.8);
}

TEST(PlaceBelief, ASecondUpdateOfTheSameFrameReplacesItsStepAndKeepsTheSpeed) {
  // The localizer updates the belief twice in a frame whose tracks were given up and relocalized at once: the second
  // estimate replaces the first, and so does its step — the speed must not start again from nothing (it did: in the
  // validation drive offset3, frames 85-94 knew no speed half the time).
  PlaceBelief belief(LinearMap(10));
  for (int t = 0; t < 4; ++t) Frame(&belief, t + 1, {Pose(4, 0.2 + 0.1 * t)});
  ASSERT_TRUE(belief.SpeedOn(4).has_value());
  belief.Update({Pose(4, 0.52)}, 4);  // frame 4 again, placed a little farther on
  ASSERT_TRUE(belief.SpeedOn(4).has_value());
  EXPECT_NEAR(*belief.SpeedOn(4), 0.1, 0.02);
  // The next frame's step starts from frame 4's last estimate, not its first.
  Frame(&belief, 5, {Pose(4, 0.62)});
  ASSERT_TRUE(belief.SpeedOn(4).has_value());
  EXPECT_NEAR(*belief.SpeedOn(4), 0.1, 0.02);
}

TEST(PlaceBelief, MotionCarriesTheMassAcrossSeveralArcsInOneFrame) {
  // Short arcs: the camera covers 2.5 arcs per frame (key-images one teach frame apart, a repeat faster than the
  // teach) — about as fast as a camera of unknown speed is expected to move, so the first placements may count as
  // outliers until they agree for a few frames; then the speed is known.
  PlaceBelief belief(LinearMap(60, {}, 1));
  const auto place = [](int t) { return Pose(1 + (5 * t) / 2, (5 * t) % 2 == 0 ? 0.2 : 0.7); };
  int t = 0;
  for (; t < 12 && !(belief.estimate().tracking && belief.SpeedOn(0)); ++t) Frame(&belief, t + 1, {place(t)});
  ASSERT_TRUE(belief.estimate().tracking) << "not tracking after " << t << " frames";
  ASSERT_TRUE(belief.SpeedOn(0).has_value());
  EXPECT_NEAR(*belief.SpeedOn(0), 2.5, 0.1);
  const GraphPlace last{belief.estimate().arc, belief.estimate().along};
  EXPECT_EQ(last.arc, place(t - 1).arc);
  // One frame without a placement: the prediction alone carries the mass 2.5 arcs on.
  belief.Predict(1);
  belief.Update({}, t + 1);
  ASSERT_TRUE(belief.Distance(last, {belief.estimate().arc, belief.estimate().along}, 4).has_value());
  EXPECT_NEAR(*belief.Distance(last, {belief.estimate().arc, belief.estimate().along}, 4), 2.5, 0.3);
  // A placement in the reconstruction of the arc of the last frame, 2.5 arc lengths past where it was (the camera
  // passed two key-images since), is evidence for the arc two or three ahead of it.
  const GraphPlace predicted{belief.estimate().arc, belief.estimate().along};
  Frame(&belief, t + 2, {Pose(predicted.arc, predicted.along + 2.5)});
  EXPECT_TRUE(belief.estimate().evidence);
  const std::optional<double> moved =
      belief.Distance(predicted, {belief.estimate().arc, belief.estimate().along}, 4);
  ASSERT_TRUE(moved.has_value());
  EXPECT_NEAR(*moved, 2.5, 0.05);
  EXPECT_GE(belief.estimate().arc, predicted.arc + 2);
}

TEST(PlaceBelief, WithoutASpeedOneFrameMovesTheCameraAFewTeachFrames) {
  // Localized on arc 5 by one placement (the speed unknown), the next frame is placed 3 arcs ahead (a relocalization
  // on a look-alike). Where the teach drive spent 5 frames on each arc, that is 15 teach frames in one frame, beyond
  // unknown_speed_max (4): an outlier, not reported. Where key-images are one teach frame apart — one frame of the
  // sequence, or 5 of a drive taught with `--every 5` (teach_frame_step) — 3 teach frames are within reach and the
  // camera is there.
  for (const auto& [frames_per_arc, step] : {std::pair{5, 1}, std::pair{1, 1}, std::pair{5, 5}}) {
    SCOPED_TRACE(::testing::Message() << frames_per_arc << " frames per arc, step " << step);
    PlaceBeliefOptions options;
    ASSERT_DOUBLE_EQ(options.unknown_speed_max, 4.0);
    options.teach_frame_step = step;
    PlaceBelief belief(LinearMap(20, {}, frames_per_arc), options);
    Frame(&belief, 1, {Pose(5, 0.5)});
    ASSERT_EQ(belief.estimate().arc, 5);
    ASSERT_FALSE(belief.SpeedOn(5).has_value());
    Frame(&belief, 2, {Pose(8, 0.5)});
    if (frames_per_arc / step == 5) {
      EXPECT_FALSE(belief.estimate().evidence);
      EXPECT_FALSE(belief.estimate().tracking);
    } else {
      EXPECT_TRUE(belief.estimate().evidence);
      EXPECT_EQ(belief.estimate().arc, 8);
    }
  }
}

TEST(PlaceBelief, AtAJunctionTheMassSpreadsIntoEveryOutgoingArc) {
  // 0 -> 1 -> 2, and at node 2 two branches: arc 2 to node 3 and arc 3 to node 4.
  Map map = LinearMap(2);
  for (node_t id : {3, 4}) {
    MapNode node;
    node.id = id;
    node.source_frame = 30;  // both branches taught over 10 frames
    map.AddNode(node);
  }
  MapArc left;
  left.id = 2;
  left.from = 2;
  left.to = 3;
  map.AddArc(left);
  MapArc right;
  right.id = 3;
  right.from = 2;
  right.to = 4;
  map.AddArc(right);
  PlaceBelief belief(map);
  ASSERT_EQ(belief.Successors(1).size(), 2u);
  for (int t = 0; t < 4; ++t) Frame(&belief, t + 1, {Pose(1, 0.3 + 0.2 * t)});  // 0.9 on arc 1
  for (int t = 4; t < 6; ++t) Frame(&belief, t + 1, {});                    // then 1.3: past the junction
  EXPECT_NEAR(belief.Mass(2), belief.Mass(3), 1e-9);
  EXPECT_GT(belief.Mass(2) + belief.Mass(3), 0.8);
  EXPECT_FALSE(belief.estimate().tracking);
  // Evidence on one branch decides.
  Frame(&belief, 7, {Pose(3, 0.5)});
  EXPECT_EQ(belief.estimate().arc, 3);
  EXPECT_TRUE(belief.estimate().tracking);
}

// The junction of the previous test with a plan through the right branch (arc 3): the prediction follows the plan,
// and placements on the branch not planned (the robot went the other way) overrule it within a few frames.
TEST(PlaceBelief, AtAJunctionAPlanSendsTheMassIntoThePlannedBranch) {
  Map map = LinearMap(2);
  for (node_t id : {3, 4}) {
    MapNode node;
    node.id = id;
    node.source_frame = 30;
    map.AddNode(node);
  }
  for (const auto& [id, to] : {std::pair<arc_t, node_t>{2, 3}, {3, 4}}) {
    MapArc arc;
    arc.id = id;
    arc.from = 2;
    arc.to = to;
    map.AddArc(arc);
  }
  PlaceBeliefOptions options;
  PlaceBelief belief(map, options);
  belief.SetPlannedArcs({0, 1, 3});
  for (int t = 0; t < 4; ++t) Frame(&belief, t + 1, {Pose(1, 0.3 + 0.2 * t)});
  for (int t = 4; t < 6; ++t) Frame(&belief, t + 1, {});
  const double branches = belief.Mass(2) + belief.Mass(3);
  ASSERT_GT(branches, 0.8);
  // planned_branch_probability of what went past the junction, up to the jumps spread over the map.
  EXPECT_NEAR(belief.Mass(3) / branches, options.planned_branch_probability, 0.01);
  EXPECT_EQ(belief.estimate().arc, 3);
  EXPECT_FALSE(belief.estimate().tracking);  // no evidence: a prior does not make a place
  // The robot took the other branch: its placements there win.
  int first_tracking = -1;
  for (int t = 0; t < 5 && first_tracking < 0; ++t) {
    Frame(&belief, 7 + t, {Pose(2, 0.5 + 0.1 * t)});
    if (belief.estimate().tracking) first_tracking = t;
  }
  EXPECT_GE(first_tracking, 0);
  EXPECT_LE(first_tracking, 2);
  EXPECT_EQ(belief.estimate().arc, 2);
  // Forgetting the plan splits equally again.
  PlaceBelief unplanned(map, options);
  unplanned.SetPlannedArcs({0, 1, 3});
  unplanned.SetPlannedArcs({});
  for (int t = 0; t < 4; ++t) Frame(&unplanned, t + 1, {Pose(1, 0.3 + 0.2 * t)});
  for (int t = 4; t < 6; ++t) Frame(&unplanned, t + 1, {});
  EXPECT_NEAR(unplanned.Mass(2), unplanned.Mass(3), 1e-9);
}

TEST(PlaceBelief, OneWrongPlacementDoesNotMoveItButConsistentEvidenceDoes) {
  PlaceBelief belief(LinearMap(30));
  for (int t = 0; t < 5; ++t) Frame(&belief, t + 1, {Pose(4, 0.1 + 0.1 * t)});
  ASSERT_EQ(belief.estimate().arc, 4);
  // A placement two arcs ahead (an absolute pose from a few wrong features): an outlier, no evidence this frame.
  const std::vector<double> inlier = [&] {
    belief.Predict(1);
    return belief.Update({Pose(4, 2.6)}, 6);
  }();
  EXPECT_LT(inlier[0], 0.5);
  EXPECT_EQ(belief.estimate().arc, 4);
  EXPECT_FALSE(belief.estimate().tracking);
  // The robot was carried to arc 20: placements there, frame after frame, win after a few frames, and the frames in
  // between are not `tracking`.
  int first_tracking = -1;
  for (int t = 0; t < 10; ++t) {
    Frame(&belief, 7 + t, {Pose(20, 0.2 + 0.05 * t)});
    if (belief.estimate().tracking && first_tracking < 0) first_tracking = t;
    if (belief.estimate().tracking) {
      EXPECT_EQ(belief.estimate().arc, 20);
    }
  }
  EXPECT_GE(first_tracking, 1);
  EXPECT_LE(first_tracking, 6);
}

TEST(PlaceBelief, NearANodeTheNeighbouringArcCountsForTheConfidence) {
  PlaceBelief belief(LinearMap(10));
  for (int t = 0; t < 5; ++t) Frame(&belief, t + 1, {Pose(3, 0.6 + 0.1 * t)});  // 1.0: on node 4
  const PlaceEstimate& estimate = belief.estimate();
  EXPECT_TRUE(estimate.arc == 3 || estimate.arc == 4);
  EXPECT_GT(belief.Mass(3), 0.2);
  EXPECT_GT(belief.Mass(4), 0.2);
  EXPECT_TRUE(estimate.tracking);
  EXPECT_GT(estimate.confidence, 0.95);
}

TEST(PlaceBelief, PastANodeTheArcAheadIsReported) {
  // Arc 4 is three times as long as arc 3 (the scale stored at node 4): a camera 0.1 of arc 3 past node 4 is within
  // the node tolerance of both arcs, whose confidences are then nearly equal. The arc holding the posterior mean is
  // reported, not the one the camera has left.
  PlaceBelief belief(LinearMap(10, {1.0, 1.0, 1.0, 3.0}));
  for (int t = 0; t < 6; ++t) Frame(&belief, t + 1, {Pose(3, 0.1 + 0.2 * t, 0.15)});  // the last at 1.1 on arc 3's line
  const PlaceEstimate& estimate = belief.estimate();
  EXPECT_TRUE(estimate.tracking);
  // Arc 3's confidence is the larger (its tolerance reaches 0.45 of its lengths into arc 4, arc 4's only 0.15 back
  // into arc 3), but the mass is past node 4.
  EXPECT_GT(belief.Confidence(3), belief.Confidence(4));
  EXPECT_GT(belief.Mass(4), belief.Mass(3));
  EXPECT_EQ(estimate.arc, 4);
  EXPECT_NEAR(estimate.along, 0.1 / 3.0, 0.03);  // 0.1 arc lengths of arc 3 past node 4
  EXPECT_NEAR(estimate.confidence, belief.Confidence(4), 1e-12);
}

TEST(PlaceBelief, PastTheRoutesEndTheCameraIsOnItsLastArc) {
  // The repeat drive goes on past the last key-image: placements beyond the last arc's end are evidence for the
  // last arc (the topological truth's convention), at positions beyond 1.
  PlaceBelief belief(LinearMap(5));
  for (int t = 0; t < 8; ++t) Frame(&belief, t + 1, {Pose(4, 0.5 + 0.15 * t)});
  EXPECT_TRUE(belief.estimate().tracking);
  EXPECT_EQ(belief.estimate().arc, 4);
  EXPECT_NEAR(belief.estimate().along, 1.55, 0.05);
  EXPECT_GT(belief.Mass(4), 0.99);
  EXPECT_TRUE(belief.Successors(4).empty());
  // More than an arc past the end the camera is off the map: placements there are not evidence of the last arc.
  for (int t = 8; t < 16; ++t) Frame(&belief, t + 1, {Pose(4, 0.5 + 0.15 * t)});
  EXPECT_FALSE(belief.estimate().tracking);
  EXPECT_FALSE(belief.estimate().evidence);
  EXPECT_GT(belief.OffMap(), 0.5);
  // And before the first key-image, on the first arc at a negative position.
  PlaceBelief reversing(LinearMap(5));
  for (int t = 0; t < 6; ++t) Frame(&reversing, t + 1, {Pose(0, 0.3 - 0.1 * t)});
  EXPECT_EQ(reversing.estimate().arc, 0);
  EXPECT_NEAR(reversing.estimate().along, -0.2, 0.05);
}

// LinearMap(5) without arc 3: two pieces, arcs 0-2 (nodes 0-3, teach frames 0-30) and arc 4 (nodes 4-5, frames
// 40-50), and a gap of one arc's length between node 3 and node 4.
Map MapInTwoPieces() {
  const Map map = LinearMap(5);
  Map pieces;
  for (const MapNode& node : map.nodes()) pieces.AddNode(node);
  for (const MapArc& arc : map.arcs()) {
    if (arc.id != 3) pieces.AddArc(arc);
  }
  return pieces;
}

TEST(PlaceBelief, PastTheEndOfADisconnectedPieceTheCameraCrossesTheGapIntoTheNextPiece) {
  // Two pieces: arcs 0-2 (nodes 0-3, teach frames 0-30) and arc 4 (nodes 4-5, frames 40-50); teach made no arc from
  // node 3 to node 4. The drive went on past node 3 through the gap (10 teach frames: one arc of arc 2's length)
  // into the second piece: a tenth of an arc past node 3 is still arc 2; 2.3 arcs past node 3's arc start, the
  // camera is 0.3 along arc 4 — where kitti07 at 320 px on every 3rd frame crosses a gap in one frame, and the
  // belief, which ended the piece in a virtual arc leading nowhere, reported the piece's last arc two arcs behind.
  const Map pieces = MapInTwoPieces();
  PlaceBelief early(pieces);
  for (int t = 0; t < 4; ++t) Frame(&early, t + 1, {Pose(2, 0.5 + 0.2 * t)});  // 1.1 at t = 3
  EXPECT_TRUE(early.estimate().tracking);
  EXPECT_EQ(early.estimate().arc, 2);
  PlaceBelief belief(pieces);
  for (int t = 0; t < 10; ++t) Frame(&belief, t + 1, {Pose(2, 0.5 + 0.2 * t)});  // 2.3 at t = 9
  EXPECT_TRUE(belief.estimate().evidence);
  EXPECT_TRUE(belief.estimate().tracking);
  EXPECT_EQ(belief.estimate().arc, 4);
  EXPECT_NEAR(belief.estimate().along, 0.3, 0.05);
  EXPECT_LT(belief.OffMap(), 0.01);
  // Backwards from the second piece the camera goes back through the gap onto arc 2.
  PlaceBelief back(pieces);
  for (int t = 0; t < 8; ++t) Frame(&back, t + 1, {Pose(4, 0.5 - 0.2 * t)});  // -0.9 at t = 7: 0.1 past node 3
  EXPECT_EQ(back.estimate().arc, 2);
  EXPECT_TRUE(back.estimate().tracking);
  // A camera standing in the gap (a car that stopped there) is on no arc of the map; the truth tolerates both arcs
  // around the gap, and so does the confidence: the belief spreads over the gap and the next piece's start, and
  // either arc stays reported (a robot that stops when lost would otherwise stay there).
  PlaceBelief standing(pieces);
  for (int t = 0; t < 5; ++t) Frame(&standing, t + 1, {Pose(2, 0.5 + 0.25 * t)});  // 1.5 at t = 4
  for (int t = 5; t < 15; ++t) Frame(&standing, t + 1, {Pose(2, 1.5)});
  EXPECT_TRUE(standing.estimate().tracking);
  EXPECT_GT(standing.Confidence(2), 0.95);
  EXPECT_GT(standing.Confidence(4), 0.95);
  // Across the gap the next piece's first arc continues the last one (the localizer's transitions follow these).
  EXPECT_EQ(belief.Successors(2), std::vector<arc_t>{4});
  EXPECT_EQ(belief.Predecessors(4), std::vector<arc_t>{2});
}

TEST(PlaceBelief, AcrossAGapTheArcOnTheSideOfTheMassIsReported) {
  // The pieces of the test above (arcs 0-2, the gap of one arc length, arc 4). The tracks stay on arc 2 while the
  // camera drives through the gap: on the gap both arcs are right, past it only arc 4, so once the mass lies past
  // the gap the report is arc 4 although arc 2's confidence (its mass and the gap's) may still be high.
  const Map pieces = MapInTwoPieces();
  PlaceBelief belief(pieces);
  for (int t = 0; t < 3; ++t) Frame(&belief, t + 1, {Pose(2, 0.2 + 0.2 * t)});  // 0.6 at t = 2: on arc 2
  EXPECT_EQ(belief.ReportedArc(2), 2);
  for (int t = 3; t < 10; ++t) Frame(&belief, t + 1, {Pose(2, 0.2 + 0.2 * t)});  // 2.0 at t = 9: node 4
  for (int t = 10; t < 12; ++t) Frame(&belief, t + 1, {Pose(4, 0.2 * t - 1.8)});  // 0.4 on arc 4 at t = 11
  ASSERT_TRUE(belief.estimate().tracking);
  ASSERT_EQ(belief.estimate().arc, 4);
  EXPECT_GT(belief.Confidence(4), belief.Confidence(2));
  EXPECT_EQ(belief.ReportedArc(2), 4);
  // Two arcs that meet at a node are both right near it: the tracked one stays reported.
  PlaceBelief joined(LinearMap(5));
  for (int t = 0; t < 6; ++t) Frame(&joined, t + 1, {Pose(1, 0.4 + 0.2 * t)});  // 1.4 at t = 5: arc 2
  ASSERT_EQ(joined.estimate().arc, 2);
  EXPECT_EQ(joined.ReportedArc(1), 1);
  // Nor does an arc that is not the belief's, nor one off the map, change anything.
  EXPECT_EQ(belief.ReportedArc(0), 0);
  EXPECT_EQ(belief.ReportedArc(kInvalidArcId), kInvalidArcId);
}

TEST(PlaceBelief, OptionsAreChecked) {
  PlaceBeliefOptions options;
  options.bins_per_arc = 1;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("bins_per_arc"), std::string::npos);
  options = PlaceBeliefOptions();
  options.jump_probability = 0.0;
  EXPECT_FALSE(options.Check());
  options = PlaceBeliefOptions();
  options.teach_frame_step = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("teach_frame_step"), std::string::npos);
  options = PlaceBeliefOptions();
  options.planned_branch_probability = 1.0;  // a plan the robot could never leave
  EXPECT_FALSE(options.Check());
  options.jump_probability = 0.0;
  EXPECT_THROW(PlaceBelief(LinearMap(2), options), std::invalid_argument);
}

TEST(PlaceBelief, AMeasurementsOwnSupportCountsTheArcAndTheToleranceAtItsNodes) {
  // Arcs of lengths 1, 2, 2 (scale 2 at node 1): arc 1 spans [0, 2] in common units from its start, and Confidence
  // also counts the last 0.15 of arc 0 (0.15 units) and the first 0.15 of arc 2 (0.3 units).
  const PlaceBelief belief(LinearMap(3, {2.0, 1.0}));
  const auto normal_cdf = [](double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); };
  // In the middle of arc 1 with σ 0.25 of arc 1 (0.5 units): the span is [-0.15, 2.3], 1 unit from the centre on
  // the left and 1.3 on the right.
  const PlaceMeasurement middle{1, 0.5, 0.25, 0.2};
  EXPECT_NEAR(belief.MeasurementSupport(1, middle), normal_cdf(1.3 / 0.5) - normal_cdf(-1.15 / 0.5), 1e-12);
  // The same place measured on the neighbouring arcs' lines: the same support.
  EXPECT_NEAR(belief.MeasurementSupport(1, PlaceMeasurement{0, 2.0, 0.5, 0.2}), belief.MeasurementSupport(1, middle),
              1e-12);
  EXPECT_NEAR(belief.MeasurementSupport(1, PlaceMeasurement{2, -0.5, 0.25, 0.2}), belief.MeasurementSupport(1, middle),
              1e-12);
  // Near a node a coarse placement supports neither arc as surely as a confident belief needs.
  const PlaceMeasurement near_node{1, 0.95, 0.25, 0.2};
  EXPECT_LT(belief.MeasurementSupport(1, near_node), 0.95);
  EXPECT_LT(belief.MeasurementSupport(2, near_node), 0.95);
  EXPECT_GT(belief.MeasurementSupport(1, PlaceMeasurement{1, 0.5, 0.05, 0.2}), 0.999);
  // Out of reach: no support.
  const PlaceBelief far(LinearMap(10));
  EXPECT_EQ(far.MeasurementSupport(9, PlaceMeasurement{0, 0.5, 0.1, 0.2}), 0.0);
}

}  // namespace
}  // namespace retrace
