#include "retrace/geometry/five_point.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/essential.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

Rigid3d MakePose(double angle_deg, const Vector3d& axis, const Vector3d& translation) {
  return Rigid3d(Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix(),
                 translation);
}

// Distance of two essential matrices up to scale and sign (both normalised to unit Frobenius norm).
double EssentialDistance(const Matrix3d& a, const Matrix3d& b) {
  const Matrix3d an = a.normalized(), bn = b.normalized();
  return std::min((an - bn).norm(), (an + bn).norm());
}

struct KnownAnswerRun {
  int samples = 0;
  int found = 0;               // the true E among the solutions (distance < 1e-6)
  std::vector<double> errors;  // distance of the closest solution to the true E, per sample
  int max_solutions = 0;
};

// Noise-free five-point samples of synthetic scenes (known b_from_a): checks every solution against the constraints
// it must satisfy and records how close the closest one comes to the true E = [t]ₓ R.
KnownAnswerRun RunKnownAnswers(const CameraModel& camera, const Rigid3d& b_from_a, int num_samples) {
  KnownAnswerRun run;
  const Matrix3d truth = EssentialFromPose(b_from_a);
  for (int seed = 1; seed <= num_samples; ++seed) {
    SyntheticTwoViewOptions options;
    options.num_points = 5;
    options.noise_px = 0.0;
    options.outlier_ratio = 0.0;
    options.min_distance = 2.0;
    options.max_distance = 40.0;
    options.seed = static_cast<uint64_t>(seed);
    const SyntheticTwoView scene = GenerateTwoView(camera, b_from_a, options);
    if (scene.bearings_a.size() != 5u) {
      ADD_FAILURE() << "scene of seed " << seed << " has " << scene.bearings_a.size() << " points";
      continue;
    }
    std::vector<Matrix3d> essentials;
    SolveEssentialFivePoint(scene.bearings_a.data(), scene.bearings_b.data(), &essentials);
    ++run.samples;
    run.max_solutions = std::max(run.max_solutions, static_cast<int>(essentials.size()));
    double best = 1e9;
    for (const Matrix3d& e : essentials) {
      EXPECT_NEAR(e.norm(), 1.0, 1e-12);
      for (int i = 0; i < 5; ++i) {
        EXPECT_LT(std::abs(scene.bearings_b[i].dot(e * scene.bearings_a[i])), 1e-9) << "seed " << seed;
      }
      // An essential matrix has two equal singular values and a zero one (Hartley & Zisserman 2003, Result 9.18).
      const Eigen::JacobiSVD<Matrix3d> svd(e);
      EXPECT_NEAR(svd.singularValues()[0], svd.singularValues()[1], 1e-7) << "seed " << seed;
      EXPECT_LT(svd.singularValues()[2], 1e-7) << "seed " << seed;
      best = std::min(best, EssentialDistance(e, truth));
    }
    run.errors.push_back(best);
    run.found += best < 1e-6;
  }
  std::sort(run.errors.begin(), run.errors.end());
  return run;
}

void ExpectKnownAnswers(const KnownAnswerRun& run, const char* name) {
  ASSERT_FALSE(run.errors.empty());
  std::printf("  %s: true E found in %d of %d samples, closest solution: median %.1e, max %.1e; up to %d solutions\n",
              name, run.found, run.samples, run.errors[run.errors.size() / 2], run.errors.back(),
              run.max_solutions);
  EXPECT_EQ(run.found, run.samples) << name;
  EXPECT_LE(run.max_solutions, 10);
}

TEST(FivePoint, FindsTheTrueEssentialMatrixOfPerspectiveScenes) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  ExpectKnownAnswers(RunKnownAnswers(camera, MakePose(5.0, Vector3d(0.1, 1.0, 0.05), Vector3d(0.2, 0.05, -1.0)), 200),
                     "forward motion with a turn");
  ExpectKnownAnswers(RunKnownAnswers(camera, MakePose(3.0, Vector3d(1.0, 0.2, 0.1), Vector3d(-0.5, 0.3, -0.8)), 200),
                     "general motion");
  ExpectKnownAnswers(RunKnownAnswers(camera, MakePose(10.0, Vector3d(0.0, 1.0, 0.0), Vector3d(1.0, 0.0, -0.3)), 200),
                     "sideways with yaw");
  ExpectKnownAnswers(RunKnownAnswers(camera, MakePose(0.5, Vector3d(0.3, 1.0, 0.0), Vector3d(0.0, 0.0, 1.0)), 200),
                     "pure forward, almost no rotation");
}

TEST(FivePoint, FindsTheTrueEssentialMatrixOfPanoramas) {
  // Bearings all around the sphere, including behind the camera.
  const EquirectangularCamera camera(1024, 512);
  ExpectKnownAnswers(RunKnownAnswers(camera, MakePose(40.0, Vector3d(0.2, 1.0, 0.1), Vector3d(1.0, 0.2, -0.5)), 200),
                     "panorama, 40 deg turn");
}

TEST(FivePoint, ZeroTranslationOrDegenerateSamplesGiveNoCrash) {
  // Five times the same correspondence: the constraints have rank 1, no solution is reported.
  Vector3d a[5], b[5];
  for (int i = 0; i < 5; ++i) {
    a[i] = Vector3d(0.1, 0.2, 1.0).normalized();
    b[i] = Vector3d(0.15, 0.2, 1.0).normalized();
  }
  std::vector<Matrix3d> essentials;
  SolveEssentialFivePoint(a, b, &essentials);
  EXPECT_TRUE(essentials.empty());
  // Not finite: nothing.
  a[2] = Vector3d(std::nan(""), 0.0, 1.0);
  SolveEssentialFivePoint(a, b, &essentials);
  EXPECT_TRUE(essentials.empty());
}

}  // namespace
}  // namespace retrace
