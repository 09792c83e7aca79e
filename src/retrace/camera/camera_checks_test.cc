#include "retrace/camera/camera_checks.h"

#include <gtest/gtest.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"

namespace retrace {
namespace {

// KITTI's left gray camera (sequence 07).
PerspectiveCamera Kitti(double fx = 707.0912, double cx = 601.8873, const LensDistortion& distortion = {}) {
  return PerspectiveCamera(1226, 370, fx, fx, cx, 183.1104, 0.0, distortion);
}

std::string ProblemOf(const CameraModel& camera) {
  std::string problem;
  EXPECT_FALSE(CheckCameraPlausible(camera, &problem)) << "accepted: " << DescribeCameraIntrinsics(camera);
  return problem;
}

TEST(CameraChecks, RealCalibrationsArePlausible) {
  std::string problem;
  EXPECT_TRUE(CheckCameraPlausible(Kitti(), &problem)) << problem;
  // EuRoC MAV cam0 (radial-tangential, strong barrel distortion).
  LensDistortion euroc;
  euroc.k1 = -0.28340811;
  euroc.k2 = 0.07395907;
  euroc.p1 = 0.00019359;
  euroc.p2 = 1.76187114e-05;
  EXPECT_TRUE(CheckCameraPlausible(PerspectiveCamera(752, 480, 458.654, 457.296, 367.215, 248.375, 0.0, euroc),
                                   &problem))
      << problem;
  // A fisheye under the unified model, whose corners lie outside its circle of view.
  LensDistortion fisheye;
  fisheye.k1 = -0.1;
  EXPECT_TRUE(CheckCameraPlausible(UnifiedCamera(640, 480, 1.6, 380, 380, 320, 240, 0.0, fisheye), &problem))
      << problem;
  EXPECT_TRUE(CheckCameraPlausible(EquirectangularCamera(720, 360), &problem)) << problem;
  // The plausibility of a model does not depend on the resolution it runs at.
  EXPECT_TRUE(CheckCameraPlausible(*Kitti().Scaled(320.0 / 1226.0), &problem)) << problem;
}

TEST(CameraChecks, ImplausibleFocalLengthPrincipalPointAndDistortionAreRefused) {
  // Field of view 0.00°: a focal length in the wrong unit or with a typo.
  EXPECT_NE(ProblemOf(Kitti(1e20)).find("field of view 0.00°"), std::string::npos) << ProblemOf(Kitti(1e20));
  EXPECT_NE(ProblemOf(Kitti(1e308)).find("field of view"), std::string::npos);
  EXPECT_NE(ProblemOf(Kitti(707.0, -5000.0)).find("principal point (-5000.0, 183.1) lies outside the 1226x370 image"),
            std::string::npos)
      << ProblemOf(Kitti(707.0, -5000.0));
  // k1 = 50 magnifies the image border ~10-fold; k1 = -2 folds it over.
  LensDistortion pincushion;
  pincushion.k1 = 50.0;
  EXPECT_NE(ProblemOf(Kitti(707.0, 601.9, pincushion)).find("lens distortion magnifies"), std::string::npos)
      << ProblemOf(Kitti(707.0, 601.9, pincushion));
  LensDistortion folding;
  folding.k1 = -2.0;
  const std::string folded = ProblemOf(Kitti(707.0, 601.9, folding));
  EXPECT_TRUE(folded.find("no ray") != std::string::npos || folded.find("not invertible") != std::string::npos ||
              folded.find("magnifies") != std::string::npos)
      << folded;
}

TEST(CameraChecks, ProjectionDifferenceMeasuresHowFarTwoCalibrationsDisagree) {
  EXPECT_LT(CameraProjectionDifferencePx(Kitti(), Kitti()), 1e-9);
  // A focal length 0.1 % off moves the image corners by 0.64 px (their distance from the principal point x 0.001).
  const double small = CameraProjectionDifferencePx(Kitti(), Kitti(707.0912 * 1.001));
  EXPECT_NEAR(small, 0.64, 0.02);
  // 500 vs 707 px: hundreds of pixels at the border.
  EXPECT_GT(CameraProjectionDifferencePx(Kitti(), Kitti(500.0)), 150.0);
}

}  // namespace
}  // namespace retrace
