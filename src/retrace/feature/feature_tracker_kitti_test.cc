// The reference-aligned tracker on the real KITTI 07 sequence, checked against the ground-truth poses
// (epipolar distances), with track lifetimes side by side with OpenCV's pyramidal Lucas-Kanade
// (forward-backward checked).

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/video/tracking.hpp>
#include <vector>

#include "retrace/dataset/ground_truth.h"
#include "retrace/feature/corner_detector.h"
#include "retrace/feature/feature_tracker.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

constexpr int kNumFrames = 41;  // frames 0..40 (the car turns left by 90 degrees between frames 15 and 50)
// KITTI 07 camera 0 (P0 of calib.txt), rectified, no distortion.
constexpr double kFocal = 707.0912, kCx = 601.8873, kCy = 183.1104;

// Distance (pixels) of x_b to the epipolar line of x_a, for cam_b_from_cam_a: F = K^-T [t]x R K^-1.
double EpipolarDistance(const Rigid3d& b_from_a, const Vector2d& x_a, const Vector2d& x_b) {
  Matrix3d k;
  k << kFocal, 0, kCx, 0, kFocal, kCy, 0, 0, 1;
  Matrix3d tx;
  const Vector3d& t = b_from_a.translation;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  const Matrix3d k_inv = k.inverse();
  const Matrix3d f = k_inv.transpose() * tx * b_from_a.rotation * k_inv;
  const Vector3d line = f * x_a.homogeneous();
  return std::abs(x_b.homogeneous().dot(line)) / line.head<2>().norm();
}

double Median(std::vector<double> v) {
  if (v.empty()) return -1.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct TrackRecord {
  Vector2d start = Vector2d::Zero();
  std::map<int, Vector2d> positions;  // frame -> position
  int lifetime = 0;                   // frames tracked after frame 0
};

struct LifetimeSummary {
  double mean = 0, median = 0;
  int survivors_5 = 0, survivors_10 = 0, survivors_20 = 0, survivors_40 = 0;
  double epipolar_median_10 = -1, epipolar_median_20 = -1;
};

LifetimeSummary Summarise(const std::vector<TrackRecord>& tracks, const std::vector<Rigid3d>& poses) {
  LifetimeSummary s;
  std::vector<double> lifetimes, epi10, epi20;
  const Rigid3d cam10_from_cam0 = poses[10].Inverse() * poses[0];
  const Rigid3d cam20_from_cam0 = poses[20].Inverse() * poses[0];
  for (const TrackRecord& t : tracks) {
    lifetimes.push_back(t.lifetime);
    s.survivors_10 += t.lifetime >= 10;
    s.survivors_20 += t.lifetime >= 20;
    s.survivors_40 += t.lifetime >= 40;
    s.survivors_5 += t.lifetime >= 5;
    if (t.positions.count(10))
      epi10.push_back(EpipolarDistance(cam10_from_cam0, t.start, t.positions.at(10)));
    if (t.positions.count(20))
      epi20.push_back(EpipolarDistance(cam20_from_cam0, t.start, t.positions.at(20)));
  }
  for (double l : lifetimes) s.mean += l / lifetimes.size();
  s.median = Median(lifetimes);
  s.epipolar_median_10 = Median(epi10);
  s.epipolar_median_20 = Median(epi20);
  return s;
}

TEST(FeatureTrackerKitti, EpipolarAccuracyAndLifetimesVersusLucasKanade) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  std::vector<Rigid3d> poses;  // world_from_cam
  for (const TimedPose& pose : ReadKittiPoses(kitti / "poses.txt")) poses.push_back(pose.world_from_cam);
  ASSERT_GE(poses.size(), static_cast<size_t>(kNumFrames));
  std::vector<cv::Mat> frames;
  for (int i = 0; i < kNumFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "image_0/%06d.png", i);
    frames.push_back(cv::imread((kitti / name).string(), cv::IMREAD_GRAYSCALE));
    ASSERT_FALSE(frames.back().empty()) << name;
  }

  // Full resolution (1226x370): 4 levels so that the coarsest window spans 120 px (fast motion near the
  // border).
  ImagePyramidOptions pyramid_options;
  pyramid_options.num_levels = 4;
  FeatureTrackerOptions tracker_options;
  tracker_options.num_levels = 4;
  FeatureTracker tracker(tracker_options);
  ImagePyramid pyramid(frames[0], pyramid_options);
  CornerDetectorOptions detector;
  detector.max_corners = 300;
  detector.min_distance = 15.0;
  detector.num_scales = 2;
  std::vector<cv::Point2f> start_points;
  std::vector<Vector2d> positions;
  for (const Corner& c : DetectCorners(pyramid, detector)) {
    positions.push_back(c.position);
    start_points.emplace_back(static_cast<float>(c.position.x()), static_cast<float>(c.position.y()));
  }
  ASSERT_GE(positions.size(), 200u);
  const std::vector<feature_t> ids = tracker.AddFeatures(pyramid, positions);

  // Reference-aligned tracker.
  std::vector<TrackRecord> ours(positions.size());
  std::map<feature_t, size_t> index_of;
  for (size_t i = 0; i < ids.size(); ++i) {
    ours[i].start = positions[i];
    if (ids[i] != kInvalidFeatureId) index_of[ids[i]] = i;
  }
  std::vector<double> residuals;
  std::map<TrackStatus, int> failures;
  for (int frame = 1; frame < kNumFrames; ++frame) {
    pyramid.Build(frames[frame], pyramid_options);
    for (const TrackedFeature& f : tracker.Track(pyramid)) {
      TrackRecord& record = ours[index_of.at(f.id)];
      if (f.status == TrackStatus::kTracked) {
        record.positions[frame] = f.warp.position;
        record.lifetime = frame;
        residuals.push_back(f.residual);
      } else {
        ++failures[f.status];
      }
    }
  }

  // OpenCV pyramidal LK, frame to frame, forward-backward checked (0.5 px), same corners and window.
  std::vector<TrackRecord> lk(start_points.size());
  std::vector<int> alive(start_points.size());
  std::vector<cv::Point2f> current = start_points;
  for (size_t i = 0; i < lk.size(); ++i) {
    lk[i].start = positions[i];
    alive[i] = static_cast<int>(i);
  }
  const cv::Size window(15, 15);
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  for (int frame = 1; frame < kNumFrames && !current.empty(); ++frame) {
    std::vector<cv::Point2f> next, back;
    std::vector<uchar> status, status_back;
    std::vector<float> error;
    cv::calcOpticalFlowPyrLK(frames[frame - 1], frames[frame], current, next, status, error, window, 3,
                             criteria);
    cv::calcOpticalFlowPyrLK(frames[frame], frames[frame - 1], next, back, status_back, error, window, 3,
                             criteria);
    std::vector<cv::Point2f> kept;
    std::vector<int> kept_alive;
    for (size_t k = 0; k < current.size(); ++k) {
      const cv::Point2f p = next[k];
      const bool inside =
          p.x >= 0 && p.y >= 0 && p.x <= frames[frame].cols - 1 && p.y <= frames[frame].rows - 1;
      if (!status[k] || !status_back[k] || !inside || cv::norm(back[k] - current[k]) > 0.5) continue;
      TrackRecord& record = lk[alive[k]];
      record.positions[frame] = Vector2d(p.x, p.y);
      record.lifetime = frame;
      kept.push_back(p);
      kept_alive.push_back(alive[k]);
    }
    current.swap(kept);
    alive.swap(kept_alive);
  }

  const LifetimeSummary a = Summarise(ours, poses);
  const LifetimeSummary b = Summarise(lk, poses);
  std::sort(residuals.begin(), residuals.end());
  std::printf("KITTI 07 frames 0-%d, %zu corners of frame 0 (1226x370)\n", kNumFrames - 1, positions.size());
  std::printf(
      "| tracker | mean life | median life | alive@5 | alive@10 | alive@20 | alive@40 | epipolar median @10 "
      "| @20 |\n");
  std::printf("| reference-aligned | %.1f | %.0f | %d | %d | %d | %d | %.3f px | %.3f px |\n", a.mean,
              a.median, a.survivors_5, a.survivors_10, a.survivors_20, a.survivors_40, a.epipolar_median_10,
              a.epipolar_median_20);
  std::printf("| OpenCV LK + FB check | %.1f | %.0f | %d | %d | %d | %d | %.3f px | %.3f px |\n", b.mean,
              b.median, b.survivors_5, b.survivors_10, b.survivors_20, b.survivors_40, b.epipolar_median_10,
              b.epipolar_median_20);
  if (!residuals.empty()) {
    std::printf("residuals of accepted tracks: median %.2f, 90%% %.2f, 99%% %.2f grey levels\n",
                residuals[residuals.size() / 2], residuals[residuals.size() * 9 / 10],
                residuals[residuals.size() * 99 / 100]);
  }
  for (const auto& [status, count] : failures)
    std::printf("  lost: %s x%d\n", TrackStatusName(status).c_str(), count);

  EXPECT_GE(a.survivors_10, 50);
  EXPECT_GE(a.epipolar_median_10, 0.0);
  EXPECT_LT(a.epipolar_median_10, 0.5);
}

}  // namespace
}  // namespace retrace
