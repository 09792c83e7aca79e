#pragma once

// Basic types shared by every layer of retrace.
//
// Conventions used throughout the code base:
//  - Camera frame: x right, y down, z forward (OpenCV / KITTI convention).
//  - A rigid transform is named by what it maps: `b_from_a` maps points expressed in frame a into frame b,
//    x_in_b = b_from_a * x_in_a = R * x_in_a + t.
//  - Bearing vectors are unit 3D rays in the camera frame; everything above the camera layer works on them, so one
//    code path serves perspective and omnidirectional cameras.

#include <cstdint>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace retrace {

using Vector2d = Eigen::Vector2d;
using Vector3d = Eigen::Vector3d;
using Vector4d = Eigen::Vector4d;
using Matrix3d = Eigen::Matrix3d;
using Matrix34d = Eigen::Matrix<double, 3, 4>;

// Globally unique id of a point feature (a landmark of the map).
using feature_t = int64_t;
// Id of a key-image (map node) and of an arc between two nodes.
using node_t = int64_t;
using arc_t = int64_t;
constexpr feature_t kInvalidFeatureId = -1;
constexpr node_t kInvalidNodeId = -1;
constexpr arc_t kInvalidArcId = -1;

// Rigid-body transform x_out = rotation * x_in + translation.
struct Rigid3d {
  Matrix3d rotation = Matrix3d::Identity();
  Vector3d translation = Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Matrix3d& r, const Vector3d& t) : rotation(r), translation(t) {}

  Vector3d operator*(const Vector3d& x) const { return rotation * x + translation; }
  Rigid3d operator*(const Rigid3d& other) const {
    return Rigid3d(rotation * other.rotation, rotation * other.translation + translation);
  }
  Rigid3d Inverse() const {
    const Matrix3d rt = rotation.transpose();
    return Rigid3d(rt, -rt * translation);
  }
  Matrix34d ToMatrix() const {
    Matrix34d m;
    m << rotation, translation;
    return m;
  }
};

// Angle of the rotation R_a^T R_b in degrees (0 for identical rotations).
double RotationErrorDeg(const Matrix3d& a, const Matrix3d& b);

// Angle in degrees between two directions (any length > 0).
double AngleBetweenDeg(const Vector3d& a, const Vector3d& b);

}  // namespace retrace
