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
  options.multi_view_max_residual_px = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("multi_view_max_residual_px"), std::string::npos) << error;
  options = LocalizerOptions();
  options.guided_matching_min_inliers = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("guided_matching_min_inliers"), std::string::npos) << error;
  options = LocalizerOptions();
  options.bootstrap_alternative_starts = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("bootstrap_alternative_starts"), std::string::npos) << error;
  options = LocalizerOptions();
  options.start_alternative_starts = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("start_alternative_starts"), std::string::npos) << error;
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
  options.start_retrieval_shortlist = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("start_retrieval_shortlist"), std::string::npos) << error;
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
  options = LocalizerOptions();
  options.min_global_agreeing_key_images = 0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.global_gate_candidates = 0;
  EXPECT_FALSE(options.Check());
}

// The a-contrario gate of a relocalization over the whole map: no more than a local one on maps up to
// global_gate_candidates key-images, then λ more located features per factor e of candidates.
TEST(LocalizerOptions, GlobalBootstrapFeaturesGrowWithTheLogarithmOfTheCandidates) {
  LocalizerOptions options;
  options.min_bootstrap_features = 8;
  options.global_features_per_log_candidates = 12.0;
  options.global_gate_candidates = 200;
  EXPECT_EQ(GlobalBootstrapFeatures(options, 1), 8);
  EXPECT_EQ(GlobalBootstrapFeatures(options, 200), 8);
  // 8 + 12 ln(1264 / 200) = 30.1: the map of equal blocks needs 31.
  EXPECT_EQ(GlobalBootstrapFeatures(options, 1264), 31);
  // A factor e of key-images adds 12 (543 = 200 e, rounded down).
  EXPECT_EQ(GlobalBootstrapFeatures(options, 543), 8 + 12);
  EXPECT_EQ(GlobalBootstrapFeatures(options, 544), 8 + 13);
  options.global_features_per_log_candidates = 0.0;
  EXPECT_EQ(GlobalBootstrapFeatures(options, 100000), 8);
}

// Test (3): a place verified by one key-image only needs the features of a local relocalization up to
// single_key_image_gate_candidates key-images, λ more per factor e beyond; disabled at 0.
TEST(LocalizerOptions, SingleKeyImageBootstrapFeaturesGrowFromASmallerMap) {
  LocalizerOptions options;
  options.min_bootstrap_features = 8;
  options.global_features_per_log_candidates = 12.0;
  options.single_key_image_gate_candidates = 28;
  EXPECT_EQ(SingleKeyImageBootstrapFeatures(options, 21), 8);
  EXPECT_EQ(SingleKeyImageBootstrapFeatures(options, 28), 8);
  // 8 + 12 ln(100 / 28) = 23.3; 8 + 12 ln(1264 / 28) = 53.7.
  EXPECT_EQ(SingleKeyImageBootstrapFeatures(options, 100), 24);
  EXPECT_EQ(SingleKeyImageBootstrapFeatures(options, 1264), 54);
  EXPECT_GT(SingleKeyImageBootstrapFeatures(options, 1264), GlobalBootstrapFeatures(options, 1264));
  options.single_key_image_gate_candidates = 0;
  EXPECT_EQ(SingleKeyImageBootstrapFeatures(options, 21), -1);
  EXPECT_TRUE(options.Check());
  options.single_key_image_gate_candidates = -1;
  EXPECT_FALSE(options.Check());
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
