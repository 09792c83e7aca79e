#include "retrace/teach/teach_settings.h"

#include <string>

#include <fmt/format.h>

#include "retrace/camera/camera_io.h"

namespace retrace {

void WriteTeachSettings(const CameraModel& camera, const TeachOptions& options, const Teacher& teacher,
                        MapDatabase* database, double camera_height) {
  database->SetMetadata("width", std::to_string(camera.width()));
  database->WriteCamera(camera.model_name(), camera.width(), camera.height(), CameraToYaml(camera));
  database->SetMetadata("r_p", fmt::format("{:.3f}", teacher.sigma_p_threshold_px()));
  database->SetMetadata("min_features", std::to_string(options.min_features));
  database->SetMetadata("min_features_fraction", fmt::format("{:g}", options.min_features_fraction));
  database->SetMetadata("max_residual", fmt::format("{:.2f}", options.max_residual));
  database->SetMetadata("reference_width", std::to_string(options.reference_width));
  if (camera_height > 0) database->SetMetadata("camera_height", fmt::format("{:g}", camera_height));
  database->SetMetadata("smoothing_sigma_px", fmt::format("{}", options.smoothing_sigma_px));
  // The settings that made the key-images' relocalization signatures: repeat computes them again when its own differ.
  if (options.store_signatures) {
    database->SetMetadata("signature_features", options.signature_features.Name());
    database->SetMetadata("signature_appearance", options.signature_appearance.Name());
  }
}

}  // namespace retrace
