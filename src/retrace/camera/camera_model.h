#pragma once

// The camera interface every layer above `camera` works with.
//
// A camera model maps 3D points in the camera frame (x right, y down, z forward) to pixels and pixels to unit
// bearing vectors. Geometry, tracking and mapping only see bearings and pixels through this interface, so the same
// code path serves perspective and omnidirectional cameras (design §2).
//
// Pixel convention: the centre of the top-left pixel is (0, 0) (OpenCV convention).

#include <memory>
#include <string>

#include "retrace/util/types.h"

namespace retrace {

enum class CameraModelType {
  kPerspective,      // K (fx, fy, skew, cx, cy) + radial distortion (k1, k2, k3) with a fitted inverse.
  kEquirectangular,  // Full 360x180 degree panorama.
  kUnified,          // Unified central catadioptric / fisheye model (Mei 2007): xi + K + radial-tangential.
};

class CameraModel {
 public:
  virtual ~CameraModel() = default;

  virtual CameraModelType type() const = 0;
  // Short name of the model, e.g. "perspective"; used in files and messages.
  virtual std::string model_name() const = 0;

  int width() const { return width_; }
  int height() const { return height_; }

  // Projects a point given in the camera frame to a pixel. Returns false when the point has no image (behind a
  // perspective camera, at the centre of projection, ...). The pixel may lie outside the image: use InImage().
  virtual bool Project(const Vector3d& point_in_cam, Vector2d* pixel) const = 0;

  // Unit bearing vector (camera frame) of the ray through `pixel`. Returns false when the pixel has no ray.
  virtual bool Unproject(const Vector2d& pixel, Vector3d* bearing) const = 0;

  // A focal length in pixels: how many pixels one radian of viewing angle spans near the image centre. Used to
  // express angular errors in pixels (e.g. for σ_p) the same way for every model.
  virtual double FocalLength() const = 0;

  // A copy of the model for images resized by `factor` (e.g. 0.26 to run 1226 px wide KITTI at 320 px).
  virtual std::unique_ptr<CameraModel> Scaled(double factor) const = 0;

  virtual std::unique_ptr<CameraModel> Clone() const = 0;

  // True when `pixel` lies inside the image, at least `margin` pixels from its border.
  bool InImage(const Vector2d& pixel, double margin = 0.0) const {
    return pixel.x() >= margin && pixel.y() >= margin && pixel.x() <= width_ - 1 - margin &&
           pixel.y() <= height_ - 1 - margin;
  }

 protected:
  CameraModel(int width, int height) : width_(width), height_(height) {}

  int width_;
  int height_;
};

}  // namespace retrace
