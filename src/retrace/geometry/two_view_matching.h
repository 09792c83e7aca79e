#pragma once

// Point correspondences between two images for two-view geometry, with OpenCV: SIFT key-points and descriptors
// (Lowe 2004), L2 nearest neighbours with the ratio test and a mutual-best check. This is the one place where the
// `retrace two-view` command and the real-data tests of this layer get their matches; the wide-baseline matcher of
// the feature layer (design §4.2, several detectors, ratio 0.6) is a separate, richer component.

#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/util/types.h"

namespace retrace {

struct TwoViewMatchingOptions {
  // Key-points kept per image (the strongest SIFT responses); 0 keeps all.
  int max_features = 8000;
  // Lowe's ratio test: keep a match when best distance < ratio * second-best distance.
  double ratio = 0.8;
  // Keep only matches that are also the best match in the other direction.
  bool mutual_best = true;

  bool Check() const { return max_features >= 0 && ratio > 0.0 && ratio <= 1.0; }
};

struct PixelMatches {
  // pixels_a[i] in image A corresponds to pixels_b[i] in image B (pixel centre of the top-left pixel = (0, 0)).
  std::vector<Vector2d> pixels_a;
  std::vector<Vector2d> pixels_b;
};

// Matches two 8-bit images (grey or colour). Empty images give no matches.
PixelMatches MatchTwoViewFeatures(const cv::Mat& image_a, const cv::Mat& image_b,
                                  const TwoViewMatchingOptions& options = TwoViewMatchingOptions());

// Lifts matches to unit bearings through the camera(s); pairs where either pixel has no ray are dropped. `kept`
// (optional) receives the index of each kept match.
void MatchesToBearings(const PixelMatches& matches, const CameraModel& camera_a, const CameraModel& camera_b,
                       std::vector<Vector3d>* bearings_a, std::vector<Vector3d>* bearings_b,
                       std::vector<int>* kept = nullptr);

}  // namespace retrace
