#pragma once

// Checks of a camera model as a whole, beyond what each file format's reader checks value by value.
//
// A calibration can be well-formed and still describe no camera retrace can work with: a focal length of 1e20 px
// (field of view 0.00°), a principal point 5000 px outside the image, a distortion polynomial that folds the image
// over or magnifies its border tenfold. Such files are typos or unit mistakes; used anyway they make teach write
// maps without arcs after minutes of work. CheckCameraPlausible() tells them apart by what the model does to the
// image, the same way for every model (through the CameraModel interface).
//
// CameraProjectionDifferencePx() compares two calibrations of the same image size by where they see the same
// rays: repeat refuses a camera that differs from the map's, since the key-images were measured with the map's.

#include <string>

#include "retrace/camera/camera_model.h"

namespace retrace {

struct CameraPlausibilityOptions {
  // Narrowest field of view across the image, horizontally and vertically, in degrees. Below a degree the image
  // holds no structure a moving vehicle could track.
  double min_field_of_view_deg = 1.0;
  // A pixel's ray must project back onto the pixel within this distance (the model's two directions agree).
  double max_round_trip_error_px = 0.05;
  // Largest radial magnification dr_d/dr of the lens distortion over the image's inscribed ellipse (1 at the
  // image centre). Real pincushion lenses stay near 1; beyond this the polynomial describes no lens. (Barrel
  // distortion lowers it towards 0, where the model folds over: that is refused as a pixel without a ray.)
  double max_distortion_magnification = 5.0;
  // Pixels per side of the grid the checks run on.
  int grid_size = 17;
};

// True when `camera` is plausible; otherwise false and a one-line `problem` (without the file name) saying what is
// wrong and with which values.
bool CheckCameraPlausible(const CameraModel& camera, std::string* problem,
                          const CameraPlausibilityOptions& options = {});

// Largest distance in pixels between where `a` and `b` image the rays of a grid of `a`'s pixels (rays `b` cannot
// image count as infinitely far). Both cameras must have the same image size.
double CameraProjectionDifferencePx(const CameraModel& a, const CameraModel& b, int grid_size = 17);

// "fx 707.1 fy 707.1 cx 601.9 cy 183.1" (and xi, k1.. where the model has them) for messages.
std::string DescribeCameraIntrinsics(const CameraModel& camera);

}  // namespace retrace
