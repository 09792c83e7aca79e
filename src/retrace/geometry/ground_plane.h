#pragma once

// The ground plane between two key-images, found by aligning the road they both see (the metric scale of an arc
// for path tracking; design §6).
//
// An arc's reconstruction has its own unit (its key-images are 1 apart). A robot's camera rides at a known,
// constant height h above the ground, so the ground plane in the arc's frame gives the arc's metric scale — metres
// per unit = h / d, d the camera centre's distance to the plane in arc units — and the "up" against which the
// robot's lateral offset and heading are measured.
//
// The arc's mapped features rarely lie on the road (they are the ones that stay visible over the arc: facades,
// trees; the simulated town's maps have almost none below the horizon), so the plane is found directly from the
// key-images: the ground plane nᵀX = d of camera b induces the homography between the two views (Hartley &
// Zisserman 2004, §13.1, result 13.1)
//
//   x_a ~ R x_b + (mᵀ x_b) t,     m = n / d,     (R, t) = a_from_b,
//
// and m (three unknowns, with the relative pose known) is the one that makes the road seen at the bottom of key-image
// b look the same when fetched from key-image a: Gauss-Newton on the photometric error of a region of interest,
// coarse to fine on an image pyramid, with a robust (Huber) loss against what is not road (kerbs, cars, pedestrians).
// The bottom of b shows ground a few metres ahead of b, which a sees higher up in its image. Its distance d is
// started from a one-dimensional search with n = the camera's down axis (+y).

#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/util/types.h"

namespace retrace {

struct GroundPlaneOptions {
  // Region of interest in key-image b, fractions of the image size: the road just ahead of the camera.
  double roi_top = 0.62;
  double roi_bottom = 0.97;
  double roi_left = 0.2;
  double roi_right = 0.8;
  // Pyramid levels used (coarse to fine), and Gauss-Newton iterations per level.
  int levels = 3;
  int iterations = 15;
  // Huber threshold of the photometric residuals, in robust standard deviations (1.4826 MAD).
  double huber_sigmas = 1.5;
  // The plane's normal must lie within this angle of the camera's down axis (a car's camera is tilted by a few
  // degrees, a robot's by up to ~30; a wall is ~90 degrees off).
  double max_tilt_deg = 35.0;
  // The initial search for d: from `min_distance` to `max_distance` arc units (the camera's height over the
  // key-images' baseline: 1.5 m over 0.3-30 m), geometrically spaced.
  double min_distance = 0.05;
  double max_distance = 5.0;
  int search_steps = 40;
  // The alignment is accepted when at least this fraction of the region's pixels land inside key-image a and the
  // robust RMS residual is below this many grey levels.
  double min_overlap = 0.5;
  double max_rms_residual = 20.0;
  // ... and when the standard deviation of d (from the normal equations, which take the pixels as independent, so
  // it is optimistic) is below this fraction of d: a road without texture leaves d unconstrained.
  double max_relative_sigma = 0.02;
  // The ground's normal in the camera's frame when known (unit, pointing down): only d is estimated then. A car's
  // camera keeps its mount's attitude to the road it stands on, so the normal is a constant of the robot:
  // GroundNormalOfRoute() estimates it from several arcs, which makes d far better conditioned where the road is
  // weakly textured or far (kitti07).
  std::optional<Vector3d> normal_in_camera;

  bool Check(std::string* error = nullptr) const;
};

struct GroundPlane {
  bool valid = false;
  // In the frame of key-image a (the arc's frame): n unit, from the camera down towards the ground; d > 0 the
  // distance of camera a's centre to the plane, in arc units.
  Vector3d normal = Vector3d::UnitY();
  double distance = 0.0;
  // Standard deviation of d from the Gauss-Newton normal equations and the residuals.
  double distance_sigma = 0.0;
  // The same plane in camera b's frame: its normal and the height of camera b above it (arc units; equal to
  // `distance` when the camera rides at a constant height).
  Vector3d normal_b = Vector3d::UnitY();
  double distance_b = 0.0;
  double rms_residual = 0.0;  // grey levels, robust (inliers of the Huber loss)
  double overlap = 0.0;       // fraction of the region's pixels that land inside key-image a

  // Signed height of a point (a's frame) above the plane, positive on the camera's side.
  double HeightOf(const Vector3d& point_in_a) const { return distance - normal.dot(point_in_a); }
};

// The ground plane seen by two 8-bit gray key-images of the same camera, `b_from_a` their relative pose (|t| = 1
// sets the unit). Invalid when the alignment does not converge to a plausible ground.
GroundPlane EstimateGroundPlane(const cv::Mat& image_a, const cv::Mat& image_b, const CameraModel& camera,
                                const Rigid3d& b_from_a, const GroundPlaneOptions& options = {});

// The ground's normal in the camera's frame common to several key-image pairs (a camera fixed on a vehicle): the
// normalised component-wise median of the normals (camera b's frame) of the valid planes; none when fewer than
// `min_planes` are valid.
std::optional<Vector3d> CommonGroundNormal(const std::vector<GroundPlane>& planes, int min_planes = 3);

}  // namespace retrace
