#include "retrace/repeat/map_loading.h"

#include <chrono>
#include <cmath>
#include <exception>
#include <sstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/camera/camera_io.h"
#include "retrace/map/map_database.h"
#include "retrace/repeat/taught_path.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

double ParseMetadataNumber(const std::string& text, const std::string& key, const std::filesystem::path& map) {
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size() && std::isfinite(value)) return value;
  } catch (const std::exception&) {
  }
  throw InputError(map.string(), "metadata " + key + " is not a number: '" + text + "'");
}

}  // namespace

MapForLocalizer LoadMapForLocalizer(const std::filesystem::path& path, const LocalizerOptions& base) {
  std::shared_ptr<MapDatabase> database = MapDatabase::Open(path);
  MapForLocalizer loaded;
  // The key-images and the key-points of their signatures stay in the file and are read when the localizer needs
  // them (Map::SetKeyImageLoader, SetSignatureLoader): it keeps what it derives from the few around its belief
  // (LocalizerOptions::max_cached_key_images) and the appearance of all (retrieval).
  loaded.map = database->ReadMap(/*load_images=*/false, /*load_signature_features=*/false);
  if (loaded.map.arcs().empty()) throw InputError(path.string(), "the map has no arcs");
  loaded.map.SetKeyImageLoader([database](node_t id) { return database->ReadKeyImage(id); });
  const cv::Mat first = loaded.map.KeyImage(loaded.map.nodes().front().id);
  loaded.key_image_size = first.size();
  if (const auto yaml = database->ReadCameraYaml()) {
    loaded.camera = ParseCameraText(*yaml, path.string());
    // The map's camera images its own key-images; when it does not, the map is damaged (not the sequence).
    if (loaded.camera->width() != first.cols || loaded.camera->height() != first.rows) {
      throw InputError(path.string(), fmt::format("corrupt map: its camera images {}x{} but its key-images are {}x{}",
                                                  loaded.camera->width(), loaded.camera->height(), first.cols,
                                                  first.rows));
    }
  }
  loaded.source_sequence = database->Metadata("source_sequence");
  // The tracker must pre-smooth frames as teach smoothed the key-images (maps written before this was stored
  // used the current default).
  loaded.options = base;
  if (const auto value = database->Metadata("smoothing_sigma_px")) {
    loaded.options.smoothing_sigma_px = ParseMetadataNumber(*value, "smoothing_sigma_px", path);
  }
  if (const auto value = database->Metadata("reference_width")) {
    loaded.options.reference_width = static_cast<int>(ParseMetadataNumber(*value, "reference_width", path));
  }
  // The belief's motion without a speed is bounded in teach frames (belief.h): `teach --every k` kept every k-th.
  if (const auto value = database->Metadata("frames_every")) {
    const double every = ParseMetadataNumber(*value, "frames_every", path);
    if (!(every >= 1 && every <= 1e6)) throw InputError(path.string(), "metadata frames_every out of range: " + *value);
    loaded.options.belief.teach_frame_step = static_cast<int>(every);
  }
  // The camera's height above the ground given to teach (unless repeat is given one): the metric path. And the
  // ground's normal and the arcs' ground planes teach fitted with it (StoreGroundFits), unless repeat is given a
  // normal.
  if (const auto value = database->Metadata("camera_height"); value && !(base.path.camera_height > 0)) {
    loaded.options.path.camera_height = ParseMetadataNumber(*value, "camera_height", path);
  }
  if (const auto value = database->Metadata("ground_normal"); value && !base.path.ground.normal_in_camera) {
    std::istringstream words(*value);
    std::string x, y, z, extra;
    if (!(words >> x >> y >> z) || (words >> extra)) {
      throw InputError(path.string(), "metadata ground_normal is not three numbers: '" + *value + "'");
    }
    const Vector3d normal(ParseMetadataNumber(x, "ground_normal", path), ParseMetadataNumber(y, "ground_normal", path),
                          ParseMetadataNumber(z, "ground_normal", path));
    if (std::abs(normal.norm() - 1.0) > 1e-3) {
      throw InputError(path.string(), "metadata ground_normal is not a unit vector: '" + *value + "'");
    }
    loaded.options.path.ground.normal_in_camera = normal.normalized();
    // The arcs' ground planes fitted for that normal.
    if (const auto text = database->Metadata("ground_fits")) {
      for (const auto& [id, fit] : ParseGroundFits(*text, path.string())) {
        MapArc* arc = loaded.map.MutableArc(id);
        if (arc == nullptr) throw InputError(path.string(), fmt::format("metadata ground_fits: no arc {}", id));
        arc->ground_fit = fit;
      }
    }
  }
  std::string error;
  if (!loaded.options.Check(&error)) throw InputError(path.string(), "tracking settings stored in the map: " + error);
  // The key-images' relocalization signatures (issue 16): teach stores them; a map written before (schema < 4), or
  // with other settings than this repeat's, gets them computed now, once, with a note.
  if (loaded.options.binary_relocalization) {
    const std::string features = loaded.options.relocalization_features.Name();
    const std::string appearance = loaded.options.retrieval.Name();
    const bool stored = database->Metadata("signature_features").value_or("") == features &&
                        database->Metadata("signature_appearance").value_or("") == appearance;
    // Read on demand only when made with these settings; otherwise all are computed below, and kept.
    if (stored) loaded.map.SetSignatureLoader([database](node_t id) { return database->ReadSignature(id); });
    const auto start = std::chrono::steady_clock::now();
    // Descriptors stored as differences from the key-image's own (map schema 7) are reconstructed from the key-image:
    // once, now, for a map small enough to keep them all (LocalizerOptions::max_resident_signatures).
    if (stored && loaded.map.nodes().size() <= static_cast<size_t>(loaded.options.max_resident_signatures)) {
      size_t resolved = 0;
      for (const MapNode& node : loaded.map.nodes()) {
        KeyImageSignature signature = database->ReadSignature(node.id);
        if (signature.descriptor_residual.empty()) continue;
        Localizer::ResolveSignature(loaded.map, node.id, loaded.options, &signature);
        if (signature.descriptors.empty()) continue;  // described afresh when used (NodeWideBaseline)
        loaded.map.MutableNode(node.id)->signature = std::move(signature);
        ++resolved;
      }
      if (resolved > 0) {
        spdlog::debug("{}: descriptors of {} key-images reconstructed in {:.2f} s", PrintableText(path.string()),
                      resolved, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
    }
    size_t computed = 0;
    for (const MapNode& node : loaded.map.nodes()) {
      if (stored && !node.signature.empty()) continue;
      loaded.map.MutableNode(node.id)->signature =
          Localizer::ComputeSignature(loaded.map.KeyImage(node.id), loaded.options);
      ++computed;
    }
    if (computed > 0) {
      spdlog::info("{}: {} of {} key-images have no stored relocalization signature{} (a map of an older retrace or "
                   "other settings): computed them in {:.1f} s; teach the map again to store them",
                   PrintableText(path.string()), computed, loaded.map.nodes().size(),
                   stored ? "" : " made with these settings",
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    // Retrieval by visual words, built once here and shared by every localizer given a copy of this map.
    const auto words_start = std::chrono::steady_clock::now();
    loaded.map.SetVisualWords(Localizer::BuildMapVisualWords(loaded.map, loaded.options));
    if (loaded.map.visual_words()) {
      spdlog::debug("{}: visual words: {} words for {} key-images in {:.2f} s", PrintableText(path.string()),
                    loaded.map.visual_words()->vocabulary.size(), loaded.map.nodes().size(),
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - words_start).count());
    }
  }
  return loaded;
}

std::optional<Vector3d> StoreGroundFits(MapDatabase* database, const CameraModel& camera,
                                        const TaughtPathOptions& options, TravelModel* travel) {
  Map map = database->ReadMap(/*load_images=*/false, /*load_signature_features=*/false);
  map.SetKeyImageLoader([database](node_t id) { return database->ReadKeyImage(id); });
  TaughtPath path(map, camera, options);
  const std::optional<Vector3d> normal = path.GroundNormal();
  if (!normal) return normal;
  std::string fits;
  for (const MapArc& arc : map.arcs()) {
    const MapArc::GroundFit fit = path.GroundFit(arc.id);
    fits += fmt::format("{} {:.17g} {:.17g}\n", arc.id, fit.distance_b, fit.distance_sigma);
  }
  database->SetMetadata("ground_normal", fmt::format("{:.17g} {:.17g} {:.17g}", normal->x(), normal->y(), normal->z()));
  database->SetMetadata("ground_fits", fits);
  if (travel != nullptr) *travel = path.MapTravelModel();
  return normal;
}

std::vector<std::pair<arc_t, MapArc::GroundFit>> ParseGroundFits(const std::string& text, const std::string& source) {
  std::vector<std::pair<arc_t, MapArc::GroundFit>> fits;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    std::istringstream words(line);
    std::string id, distance, sigma, extra;
    if (!(words >> id >> distance >> sigma) || (words >> extra)) {
      throw InputError(source, fmt::format("metadata ground_fits line {} is not three numbers: '{}'", number, line));
    }
    const double arc_id = ParseMetadataNumber(id, "ground_fits", source);
    const MapArc::GroundFit fit{ParseMetadataNumber(distance, "ground_fits", source),
                                ParseMetadataNumber(sigma, "ground_fits", source)};
    if (!(arc_id >= 0 && arc_id == std::floor(arc_id) && arc_id <= 2e9) || fit.distance_b < 0 ||
        fit.distance_sigma < 0) {
      throw InputError(source, fmt::format("metadata ground_fits line {}: not an arc id and two non-negative "
                                           "numbers: '{}'",
                                           number, line));
    }
    fits.emplace_back(static_cast<arc_t>(arc_id), fit);
  }
  return fits;
}

}  // namespace retrace
