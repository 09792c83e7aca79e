#include "retrace/geometry/two_view_matching.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace retrace {
namespace {

cv::Mat ToGray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

}  // namespace

PixelMatches MatchTwoViewFeatures(const cv::Mat& image_a, const cv::Mat& image_b,
                                  const TwoViewMatchingOptions& options) {
  PixelMatches matches;
  if (image_a.empty() || image_b.empty() || !options.Check()) return matches;
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(options.max_features);
  std::vector<cv::KeyPoint> keypoints_a, keypoints_b;
  cv::Mat descriptors_a, descriptors_b;
  sift->detectAndCompute(ToGray(image_a), cv::noArray(), keypoints_a, descriptors_a);
  sift->detectAndCompute(ToGray(image_b), cv::noArray(), keypoints_b, descriptors_b);
  if (keypoints_a.size() < 2 || keypoints_b.size() < 2) return matches;

  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> forward, backward;
  matcher.knnMatch(descriptors_a, descriptors_b, forward, 2);
  if (options.mutual_best) matcher.knnMatch(descriptors_b, descriptors_a, backward, 1);
  for (const std::vector<cv::DMatch>& candidates : forward) {
    if (candidates.size() < 2) continue;
    const cv::DMatch& best = candidates[0];
    if (!(best.distance < options.ratio * candidates[1].distance)) continue;
    if (options.mutual_best) {
      const auto& back = backward[best.trainIdx];
      if (back.empty() || back[0].trainIdx != best.queryIdx) continue;
    }
    const cv::Point2f& pa = keypoints_a[best.queryIdx].pt;
    const cv::Point2f& pb = keypoints_b[best.trainIdx].pt;
    matches.pixels_a.emplace_back(pa.x, pa.y);
    matches.pixels_b.emplace_back(pb.x, pb.y);
  }
  return matches;
}

void MatchesToBearings(const PixelMatches& matches, const CameraModel& camera_a, const CameraModel& camera_b,
                       std::vector<Vector3d>* bearings_a, std::vector<Vector3d>* bearings_b, std::vector<int>* kept) {
  bearings_a->clear();
  bearings_b->clear();
  if (kept) kept->clear();
  for (size_t i = 0; i < matches.pixels_a.size(); ++i) {
    Vector3d fa, fb;
    if (!camera_a.Unproject(matches.pixels_a[i], &fa) || !camera_b.Unproject(matches.pixels_b[i], &fb)) continue;
    bearings_a->push_back(fa);
    bearings_b->push_back(fb);
    if (kept) kept->push_back(static_cast<int>(i));
  }
}

}  // namespace retrace
