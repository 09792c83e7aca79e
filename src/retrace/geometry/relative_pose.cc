#include "retrace/geometry/relative_pose.h"

#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {
namespace {

opengv::bearingVectors_t ToOpengv(const std::vector<Vector3d>& bearings) {
  return opengv::bearingVectors_t(bearings.begin(), bearings.end());
}

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

// OpenGV's 5-point solver with the adapter built once per estimation.
//
// OpenGV's convention: viewpoint 1 and 2, E = [t]ₓ R with R the rotation from viewpoint 2 to 1 and t the position of
// viewpoint 2 seen from 1, so that f1ᵀ E f2 = 0. Passing B as viewpoint 1 and A as viewpoint 2 gives exactly
// retrace's E = [t]ₓ R of b_from_a with f_Bᵀ E f_A = 0.
class FivePointSolver {
 public:
  FivePointSolver(const std::vector<Vector3d>& a, const std::vector<Vector3d>& b)
      : a_(a), b_(b), opengv_b_(ToOpengv(b)), opengv_a_(ToOpengv(a)), adapter_(opengv_b_, opengv_a_) {}

  void operator()(const std::vector<int>& sample, std::vector<Rigid3d>* poses) const {
    const opengv::essentials_t essentials = opengv::relative_pose::fivept_nister(adapter_, sample);
    for (const opengv::essential_t& e : essentials) AppendPosesInFront(e, a_, b_, sample, poses);
  }

 private:
  const std::vector<Vector3d>& a_;
  const std::vector<Vector3d>& b_;
  opengv::bearingVectors_t opengv_b_;
  opengv::bearingVectors_t opengv_a_;
  opengv::relative_pose::CentralRelativeAdapter adapter_;
};

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
  FivePointSolver(bearings_a, bearings_b)(sample, poses);
}

TwoViewGeometry EstimateRelativePose(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                     double focal_length_px, const TwoViewOptions& options, const Rigid3d* guess) {
  if (bearings_a.size() != bearings_b.size() || bearings_a.size() < 5) {
    // Let the shared loop report the failure with its reason (the solver needs matching lists of 5 or more).
    return internal::EstimateTwoView(bearings_a, bearings_b, focal_length_px, options, 5,
                                     [](const std::vector<int>&, std::vector<Rigid3d>*) {},
                                     internal::PoseManifold{5, &UpdateGeneralPose});
  }
  const FivePointSolver solver(bearings_a, bearings_b);
  return internal::EstimateTwoView(
      bearings_a, bearings_b, focal_length_px, options, 5,
      [&solver](const std::vector<int>& sample, std::vector<Rigid3d>* poses) { solver(sample, poses); },
      internal::PoseManifold{5, &UpdateGeneralPose}, guess);
}

}  // namespace retrace
