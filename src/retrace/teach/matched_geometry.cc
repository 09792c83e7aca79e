#include "retrace/teach/matched_geometry.h"

#include <algorithm>

#include "retrace/geometry/relative_pose.h"

namespace retrace {
namespace {

// The bearings of a match's two key-points, appended; false (nothing appended) when one does not unproject.
bool MatchBearings(const CameraModel& camera, const MatchableImage& a, const MatchableImage& b, const cv::DMatch& m,
                   std::vector<Vector3d>* bearings_a, std::vector<Vector3d>* bearings_b) {
  const cv::Point2f& pa = a.features.keypoints[m.queryIdx].pt;
  const cv::Point2f& pb = b.features.keypoints[m.trainIdx].pt;
  Vector3d ba, bb;
  if (!camera.Unproject(Vector2d(pa.x, pa.y), &ba) || !camera.Unproject(Vector2d(pb.x, pb.y), &bb)) return false;
  bearings_a->push_back(ba);
  bearings_b->push_back(bb);
  return true;
}

}  // namespace

MatchedGeometry RelateByMatching(const CameraModel& camera, const MatchableImage& a, const MatchableImage& b,
                                 const MatchedGeometryOptions& options) {
  MatchedGeometry result;
  for (const cv::DMatch& m : MatchWideBaseline(a.features, b.features, options.matching)) {
    if (!MatchBearings(camera, a, b, m, &result.bearings_a, &result.bearings_b)) continue;
    result.matches.push_back(m);
  }
  result.geometry = EstimateRelativePose(result.bearings_a, result.bearings_b, camera.FocalLength(), options.geometry);
  result.trackable.assign(result.matches.size(), false);
  result.position_in_b.assign(result.matches.size(), Vector2d::Zero());
  if (!result.geometry.success) return result;
  for (size_t i = 0; i < result.matches.size(); ++i) {
    if (!result.geometry.inlier_mask[i]) continue;
    const cv::KeyPoint& ka = a.features.keypoints[result.matches[i].queryIdx];
    const cv::KeyPoint& kb = b.features.keypoints[result.matches[i].trainIdx];
    ReferencePatch reference;
    if (!reference.Create(a.pyramid, Vector2d(ka.pt.x, ka.pt.y), options.alignment.window_size,
                          options.reference_levels)) {
      continue;
    }
    WarpState initial;
    initial.position = Vector2d(kb.pt.x, kb.pt.y);
    initial.scale = ka.size > 0 ? kb.size / ka.size : 1.0;
    const AlignmentResult aligned = AlignToReference(b.pyramid, reference, initial, options.alignment);
    if (!aligned.ok() || (aligned.warp.position - initial.position).norm() > options.max_track_distance_px) continue;
    result.trackable[i] = true;
    result.position_in_b[i] = aligned.warp.position;
    ++result.num_trackable;
  }
  return result;
}

double AppearanceSimilarity(int consistent, size_t keypoints_a, size_t keypoints_b) {
  const size_t fewer = std::min(keypoints_a, keypoints_b);
  if (fewer == 0 || consistent <= 0) return 0.0;
  return std::min(1.0, static_cast<double>(consistent) / static_cast<double>(fewer));
}

double MatchedSimilarity(const MatchedGeometry& matched, const MatchableImage& a, const MatchableImage& b) {
  if (!matched.geometry.success) return 0.0;
  return AppearanceSimilarity(matched.geometry.num_inliers, a.features.size(), b.features.size());
}

TwoViewGeometry EstimateMatchedGeometryNear(const CameraModel& camera, const MatchedGeometry& matched,
                                            const TwoViewOptions& options, const Rigid3d& guess) {
  return EstimateRelativePose(matched.bearings_a, matched.bearings_b, camera.FocalLength(), options, &guess);
}

}  // namespace retrace
