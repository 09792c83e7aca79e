// Unit tests of the localizer's options and input checks; its behaviour on real and simulated drives is tested in
// repeat_kitti_test and repeat_sim_test, its parts in belief_test, placement_test and control/steering_test.

#include "retrace/repeat/localizer.h"

#include <gtest/gtest.h>

#include "retrace/util/error.h"

namespace retrace {
namespace {

TEST(LocalizerOptions, CheckRejectsBadValues) {
  LocalizerOptions options;
  EXPECT_TRUE(options.Check());
  options.next_arc_ratio = 0.0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_FALSE(error.empty());
  options = LocalizerOptions();
  options.max_bad_frames = 0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.agreement_sigmas = 0.0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.prediction_skipped_levels = -1;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.belief.min_confidence = 1.5;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("belief"), std::string::npos) << error;
  options = LocalizerOptions();
  options.placement.pose_sigma_floor = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("placement"), std::string::npos) << error;
  options = LocalizerOptions();
  options.pose.min_inliers = 2;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("pose"), std::string::npos) << error;
  options = LocalizerOptions();
  options.retrieval_shortlist = -1;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.retrieval_ambiguity_ratio = 1.5;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("ambiguity"), std::string::npos) << error;
  options = LocalizerOptions();
  options.relocalization_features.patch_size = 2;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("relocalization_features"), std::string::npos) << error;
  options = LocalizerOptions();
  options.relocalization_max_samples = 0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.retrieval.patch_size = 4;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("retrieval"), std::string::npos) << error;
}

TEST(Localizer, MapWithoutImagesIsBadInput) {
  Map map;
  MapNode node;
  node.id = 0;
  map.AddNode(node);
  class TinyCamera : public CameraModel {
   public:
    TinyCamera() : CameraModel(64, 48) {}
    CameraModelType type() const override { return CameraModelType::kPerspective; }
    std::string model_name() const override { return "tiny"; }
    bool Project(const Vector3d& p, Vector2d* pixel) const override {
      if (p.z() <= 0) return false;
      *pixel = Vector2d(50 * p.x() / p.z() + 32, 50 * p.y() / p.z() + 24);
      return true;
    }
    bool Unproject(const Vector2d& pixel, Vector3d* bearing) const override {
      *bearing = Vector3d((pixel.x() - 32) / 50, (pixel.y() - 24) / 50, 1).normalized();
      return true;
    }
    double FocalLength() const override { return 50; }
    std::unique_ptr<CameraModel> Scaled(double) const override { return Clone(); }
    std::unique_ptr<CameraModel> Clone() const override { return std::make_unique<TinyCamera>(); }
  };
  EXPECT_THROW(Localizer(map, TinyCamera()), InputError);
}

}  // namespace
}  // namespace retrace
