#pragma once

// Decomposed point transfer in the calibrated context (Segvic 2009 §4.4, Fig. 5; design §3.4).
//
// Predicts where a feature mapped in the arc (I_a, I_b) appears in the current image I_t:
//   1. the arc geometry W (b_from_a, |t| = 1, computed at teach time) gives the feature's 3D point Q in A's frame;
//   2. the current geometry between I_t and one key-image K of the arc (K = A or B; cur_from_k with |t| = 1 in its own
//      scale) is estimated from the features tracked now, together with its own triangulation of them;
//   3. the current geometry is brought into the frame and scale of the arc: one scale factor, the median ratio of the
//      distances of the shared features from camera K in the two reconstructions (scale.h);
//   4. Q is projected into I_t through the camera model (with its distortion).
//
// Steps 1-3 are done once per frame and arc by PointTransfer::Create (one median over the shared features); step 4 is
// one rigid transform and one projection per feature (Transfer), so the repeat phase can call it for every mapped
// feature of the current and neighbouring arcs each frame.

#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/geometry/scale.h"
#include "retrace/util/types.h"

namespace retrace {

// Which key-image of the arc a current geometry or a reference appearance belongs to.
enum class ArcImage { kA, kB };

struct PointTransferOptions {
  // Fewer shared features than this and the transfer is invalid (no reliable scale).
  int min_shared_points = 5;
  // Predictions closer than this to the image border count as outside the image, pixels.
  double image_margin_px = 0.0;

  bool Check() const { return min_shared_points >= 1 && image_margin_px >= 0.0; }
};

struct TransferredPoint {
  // Q projects through the camera model (e.g. in front of a perspective camera).
  bool projectable = false;
  // Projectable and inside the image (with the margin): worth searching for.
  bool in_image = false;
  // Predicted pixel in I_t (distorted, as it appears in the image); meaningful when projectable.
  Vector2d pixel = Vector2d::Zero();
  // |Q - C_t| / |Q - C_ref|: distance of Q to the current camera over its distance to the camera of the key-image
  // that holds the feature's reference appearance. The apparent size of the feature in I_t relative to the reference
  // is the inverse of this ratio (a feature twice as far looks half as large).
  double distance_ratio = 0.0;
};

class PointTransfer {
 public:
  PointTransfer() = default;

  // Steps 1-3. `arc_b_from_a`: the arc geometry (|t| = 1). `current_from_key`: the current geometry between I_t and
  // key-image `key` (x_t = R x_key + t, |t| arbitrary). For the shared features (tracked now and mapped in the arc),
  // `arc_points_in_a[i]` is the arc's point (A's frame, arc scale) and `current_points_in_key[i]` the current
  // geometry's triangulation of the same feature (frame of `key`, current scale).
  static PointTransfer Create(const Rigid3d& arc_b_from_a, const Rigid3d& current_from_key, ArcImage key,
                              const std::vector<Vector3d>& arc_points_in_a,
                              const std::vector<Vector3d>& current_points_in_key,
                              const PointTransferOptions& options = PointTransferOptions());

  // Step 4 for one arc point Q (A's frame, arc scale). `reference` is the key-image whose camera defines the
  // reference distance of `distance_ratio`. Must only be called on a valid() transfer.
  TransferredPoint Transfer(const Vector3d& point_in_a, const CameraModel& camera,
                            ArcImage reference = ArcImage::kA) const;

  // Step 4 for many points; `out` is resized to points_in_a.size().
  void TransferAll(const std::vector<Vector3d>& points_in_a, const CameraModel& camera, ArcImage reference,
                   std::vector<TransferredPoint>* out) const;

  // True when the scale could be estimated from enough shared features.
  bool valid() const { return valid_; }
  // The scale vote: arc units per current-geometry unit.
  const ScaleEstimate& scale() const { return scale_; }
  // The current camera in the arc's frame and scale: x_t = R x_a + t.
  const Rigid3d& current_from_a() const { return current_from_a_; }
  const Rigid3d& arc_b_from_a() const { return arc_b_from_a_; }

 private:
  bool valid_ = false;
  ScaleEstimate scale_;
  Rigid3d arc_b_from_a_;
  Rigid3d current_from_a_;
  PointTransferOptions options_;
};

}  // namespace retrace
