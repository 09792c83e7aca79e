#include "retrace/geometry/relative_pose.h"

#include "retrace/geometry/essential.h"
#include "retrace/geometry/five_point.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {
namespace {

// Appends the decompositions of `e` that put every sampled correspondence in front of both cameras.
void AppendPosesInFront(const Matrix3d& e, const std::vector<Vector3d>& a, const std::vector<Vector3d>& b,
                        const std::vector<int>& sample, std::vector<Rigid3d>* poses) {
  Rigid3d candidates[4];
  if (!DecomposeEssential(e, candidates)) return;
  for (const Rigid3d& pose : candidates) {
    bool all_in_front = true;
    for (int i : sample) {
      if (!InFrontOfBothCameras(pose, a[i], b[i])) {
        all_in_front = false;
        break;
      }
    }
    if (all_in_front) poses->push_back(pose);
  }
}

// R ← exp(δ₀₁₂) R, t ← normalize(t + δ₃ b₁ + δ₄ b₂) with (b₁, b₂) a basis of the tangent plane of the unit t.
Rigid3d UpdateGeneralPose(const Rigid3d& pose, const double* delta) {
  Vector3d b1, b2;
  TangentBasis(pose.translation, &b1, &b2);
  const Vector3d t = (pose.translation + delta[3] * b1 + delta[4] * b2).normalized();
  return Rigid3d(ExpSO3(Vector3d(delta[0], delta[1], delta[2])) * pose.rotation, t);
}

}  // namespace

internal::PoseManifold internal::GeneralPoseManifold() { return internal::PoseManifold{5, &UpdateGeneralPose}; }

void SolveFivePoint(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                    const std::vector<int>& sample, std::vector<Rigid3d>* poses) {
  if (sample.size() != 5) return;
  Vector3d sample_a[5], sample_b[5];
  for (int k = 0; k < 5; ++k) {
    sample_a[k] = bearings_a[sample[k]];
    sample_b[k] = bearings_b[sample[k]];
  }
  std::vector<Matrix3d> essentials;
  essentials.reserve(10);
  SolveEssentialFivePoint(sample_a, sample_b, &essentials);
  for (const Matrix3d& e : essentials) AppendPosesInFront(e, bearings_a, bearings_b, sample, poses);
}

TwoViewGeometry EstimateRelativePose(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                     double focal_length_px, const TwoViewOptions& options, const Rigid3d* guess) {
  if (bearings_a.size() != bearings_b.size() || bearings_a.size() < 5) {
    // Let the shared loop report the failure with its reason (the solver needs matching lists of 5 or more).
    return internal::EstimateTwoView(bearings_a, bearings_b, focal_length_px, options, 5,
                                     [](const std::vector<int>&, std::vector<Rigid3d>*) {},
                                     internal::PoseManifold{5, &UpdateGeneralPose});
  }
  return internal::EstimateTwoView(
      bearings_a, bearings_b, focal_length_px, options, 5,
      [&](const std::vector<int>& sample, std::vector<Rigid3d>* poses) {
        SolveFivePoint(bearings_a, bearings_b, sample, poses);
      },
      internal::PoseManifold{5, &UpdateGeneralPose}, guess);
}

}  // namespace retrace
