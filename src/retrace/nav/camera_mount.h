#pragma once

// How the camera is mounted against the ground the robot drives on, from the taught geometry of a map: the ground's
// normal in the camera frame, from the arcs' motions alone (no camera height, no road texture needed; the
// photometric road alignment of geometry/ground_plane.h gives the plane's distance too, for metric path tracking).
//
// Booij 2007's planar two-view geometry (geometry/planar_pose.h, eq. B.4) assumes that the camera turns only about
// its own y axis: a camera mounted level on a robot on flat ground. A camera pitched down by a few degrees (a car's
// camera; the simulator's default 5°) breaks that assumption as soon as two images differ in heading: the relative
// rotation R_mount^T R_y(ψ) R_mount is no longer about y, and the planar model keeps a third of the inliers of a
// 90° turn that the five-point model finds. Rotating every bearing by level_from_camera first makes the motion
// planar again, with the heading measured about the true vertical.
//
// The normal n of the ground plane in the camera frame (pointing down, retrace's y) follows from the map's arcs,
// which are motions of the robot over that ground:
//   - every arc's translation direction c (the second camera's centre in the first's frame) lies in the plane:
//     n · c = 0;
//   - every arc that turns (rotation angle ≥ min_turn_rad) turns about the plane's normal: n ∥ axis(R).
// n minimises nᵀ M n over unit vectors, M = Σ c cᵀ + Σ (I − a aᵀ) + ε e_x e_xᵀ (the smallest eigenvector of M,
// total least squares). A route driven straight only constrains one direction (the pitch); the small prior term
// ε e_x e_xᵀ then says the camera is not rolled (its x axis is horizontal). Constraints further from the first
// estimate than max(3 × their median, min_outlier_rad) (a wrong arc) are dropped and n is solved again.

#include <Eigen/Core>

#include "retrace/map/map.h"

namespace retrace {

struct CameraMountOptions {
  // Arcs that turn by at least this much (rad) also give the normal as their rotation axis (below it the axis of a
  // noisy estimate is ill defined).
  double min_turn_rad = 0.1;
  // Weight ε of the prior "the camera is not rolled", relative to one arc's constraint.
  double no_roll_prior_weight = 1e-3;
  // Constraints further than max(3 × median, this) from the first estimate are dropped (rad).
  double min_outlier_rad = 0.02;
};

struct CameraMount {
  Eigen::Vector3d down = Eigen::Vector3d::UnitY();  // the ground's normal in the camera frame, pointing down
  // Rotates camera-frame vectors into the level frame: y along `down`, z the camera's optical axis projected on the
  // ground, x = y × z (right). Identity for a level camera.
  Eigen::Matrix3d level_from_camera = Eigen::Matrix3d::Identity();
  int translations = 0;  // arcs whose translation constrained n (after dropping outliers)
  int rotations = 0;     // arcs whose rotation axis constrained n
  int dropped = 0;       // constraints dropped as outliers
  // Angle between `down` and the camera's y axis (rad): the camera's tilt against the ground (pitch and roll).
  double tilt_rad() const;
};

// The level frame of a camera whose ground normal (pointing down) is `down` (see CameraMount).
Eigen::Matrix3d LevelFromCamera(const Eigen::Vector3d& down);

// n from the arcs of `map` (see the header comment). A map without arcs gives a level camera.
CameraMount EstimateCameraMount(const Map& map, const CameraMountOptions& options = {});

}  // namespace retrace
