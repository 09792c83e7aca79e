#pragma once

// Relating two images by wide-baseline matching (Segvic 2009 §4.1, design §4.2): the step shared by gap recovery,
// loop closing and mapping by matching. Matches are verified by a robust two-view geometry, and every inlier is
// checked immediately with the tracker: aligned from image A's appearance at its key-point to image B near the
// matched key-point. Only such trackable matches may become map features used for localization; the others serve
// the geometry only.

#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/feature/feature_tracker.h"
#include "retrace/feature/image_pyramid.h"
#include "retrace/feature/wide_baseline.h"
#include "retrace/geometry/two_view_geometry.h"

namespace retrace {

// An image prepared for matching: the tracker's pyramid and the wide-baseline features.
struct MatchableImage {
  cv::Mat image;
  ImagePyramid pyramid;
  WideBaselineFeatures features;
};

struct MatchedGeometry {
  TwoViewGeometry geometry;        // over `matches` (index-aligned); b_from_a maps A's frame into B's
  std::vector<cv::DMatch> matches;  // queryIdx: key-point of A, trainIdx: key-point of B
  std::vector<Vector3d> bearings_a, bearings_b;  // of each match (the geometry's correspondences)
  // Per match: an inlier that the tracker follows from A to B, and where it converged in B.
  std::vector<bool> trackable;
  std::vector<Vector2d> position_in_b;
  int num_trackable = 0;

  Vector2d PositionInA(const MatchableImage& a, size_t i) const {
    const cv::Point2f& p = a.features.keypoints[matches[i].queryIdx].pt;
    return Vector2d(p.x, p.y);
  }
};

struct MatchedGeometryOptions {
  WideBaselineOptions matching;
  TwoViewOptions geometry;
  AlignmentOptions alignment;
  int reference_levels = 3;  // pyramid levels of the references cut in A
  // A trackable match must converge within this distance (pixels) of its matched key-point in B.
  double max_track_distance_px = 3.0;
};

// Matches A with B, estimates the geometry and checks trackability. Never throws; geometry.success tells.
MatchedGeometry RelateByMatching(const CameraModel& camera, const MatchableImage& a, const MatchableImage& b,
                                 const MatchedGeometryOptions& options);

// Appearance similarity (Booij 2007 §B.2): `consistent` matches (those of the epipolar geometry) over the fewer
// key-points of the two images, in [0, 1]; 0 when either has none.
double AppearanceSimilarity(int consistent, size_t keypoints_a, size_t keypoints_b);

// AppearanceSimilarity of A and B over their wide-baseline key-points; 0 when the geometry failed.
double MatchedSimilarity(const MatchedGeometry& matched, const MatchableImage& a, const MatchableImage& b);

// The geometry of the matches of `matched` (between A and B) estimated again with `guess` as the first hypothesis:
// the refined guess is kept unless a sampled motion fits the matches clearly better (TwoViewOptions::
// guess_preference). A second look at a pair whose matches fit several motions almost equally well.
TwoViewGeometry EstimateMatchedGeometryNear(const CameraModel& camera, const MatchedGeometry& matched,
                                            const TwoViewOptions& options, const Rigid3d& guess);

}  // namespace retrace
