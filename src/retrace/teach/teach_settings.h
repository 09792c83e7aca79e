#pragma once

// What a map records of the teach that wrote it, besides the map itself: the camera of the key-images and the
// settings that repeat must apply the same way (reference_width, smoothing_sigma_px: the tracker pre-smooths frames
// as teach smoothed the key-images, or the residual threshold R means something else against them; see
// repeat/map_loading.h), the camera's height above the ground when it was given (repeat's metric path,
// repeat/taught_path.h), plus r_p, n and R for `retrace inspect`. Every writer of maps (`retrace teach`, the Python
// bindings) stores them through this one function, so their maps localize alike.

#include "retrace/camera/camera_model.h"
#include "retrace/map/map_database.h"
#include "retrace/teach/teacher.h"

namespace retrace {

// Writes the camera and the settings of `teacher` (constructed with `camera` and `options`) into `database`.
// `camera_height`: metres above the ground, stored only when positive (0 = not given).
void WriteTeachSettings(const CameraModel& camera, const TeachOptions& options, const Teacher& teacher,
                        MapDatabase* database, double camera_height = 0.0);

}  // namespace retrace
