#include "retrace/geometry/point_transfer.h"

namespace retrace {

PointTransfer PointTransfer::Create(const Rigid3d& arc_b_from_a, const Rigid3d& current_from_key, ArcImage key,
                                    const std::vector<Vector3d>& arc_points_in_a,
                                    const std::vector<Vector3d>& current_points_in_key,
                                    const PointTransferOptions& options) {
  PointTransfer transfer;
  transfer.arc_b_from_a_ = arc_b_from_a;
  transfer.options_ = options;
  if (!options.Check() || arc_points_in_a.size() != current_points_in_key.size()) return transfer;
  // Step 3 (Segvic 2009 §4.4): both reconstructions seen from camera `key`; one scale factor from the median of the
  // distance ratios.
  const Rigid3d key_from_a = key == ArcImage::kA ? Rigid3d() : arc_b_from_a;
  transfer.scale_ = EstimateScale(arc_points_in_a, key_from_a, current_points_in_key, Rigid3d(),
                                  options.min_shared_points);
  if (!transfer.scale_.success) return transfer;
  const Rigid3d scaled_current_from_key(current_from_key.rotation,
                                        transfer.scale_.scale * current_from_key.translation);
  transfer.current_from_a_ = scaled_current_from_key * key_from_a;
  transfer.valid_ = transfer.current_from_a_.rotation.allFinite() && transfer.current_from_a_.translation.allFinite();
  return transfer;
}

TransferredPoint PointTransfer::Transfer(const Vector3d& point_in_a, const CameraModel& camera,
                                         ArcImage reference) const {
  TransferredPoint result;
  if (!valid_) return result;
  const Vector3d in_current = current_from_a_ * point_in_a;
  const Vector3d in_reference = reference == ArcImage::kA ? point_in_a : arc_b_from_a_ * point_in_a;
  const double reference_distance = in_reference.norm();
  result.distance_ratio = reference_distance > 0.0 ? in_current.norm() / reference_distance : 0.0;
  result.projectable = camera.Project(in_current, &result.pixel) && result.pixel.allFinite();
  result.in_image = result.projectable && camera.InImage(result.pixel, options_.image_margin_px);
  return result;
}

void PointTransfer::TransferAll(const std::vector<Vector3d>& points_in_a, const CameraModel& camera,
                                ArcImage reference, std::vector<TransferredPoint>* out) const {
  out->resize(points_in_a.size());
  for (size_t i = 0; i < points_in_a.size(); ++i) (*out)[i] = Transfer(points_in_a[i], camera, reference);
}

}  // namespace retrace
