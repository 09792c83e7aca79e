#pragma once

// Steering from the image (Segvic 2009 §6.3, eq. (10)): a proportional law on image coordinates.
//
//   w = k · mean_j (x_t,j − x*_j)
//
// over the features of the current arc, x_t,j the horizontal normalised coordinate of feature j in the current
// image and x*_j its coordinate in the next key-image (the one the robot drives towards). Image x grows to the
// right, so w < 0 turns left, towards where the next key-image looks.

#include <limits>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct SteeringCommand {
  double angle = 0.0;  // w of eq. (10), radians; 0 when not valid
  bool valid = false;  // at least one feature was seen in front of both cameras
  int features = 0;    // features averaged
};

// One feature: its bearing in the current camera and in the next key-image (unit vectors, camera frames).
struct SteeringFeature {
  Vector3d current;
  Vector3d target;
};

// eq. (10) with gain `gain` (radians per unit of normalised coordinate, Segvic 2009: k); features behind either
// camera, or with a normalised coordinate |x| beyond `max_abs_x` in either (outside the forward field the law is
// made for: an omnidirectional camera's features beside the robot slide with its forward motion, x = tan of their
// angle grows without bound, and a lateral offset unbalances them), are skipped.
SteeringCommand SteerByImage(const std::vector<SteeringFeature>& features, double gain,
                             double max_abs_x = std::numeric_limits<double>::infinity());

}  // namespace retrace
