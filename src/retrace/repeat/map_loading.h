#pragma once

// Opening a taught map for localization, as every user of the Localizer does (`retrace repeat`, `retrace sim drive`,
// the Python bindings): the map with its key-images, the camera it stores, and the tracking settings teach stored
// in its metadata (repeat must pre-smooth its frames exactly as teach smoothed the key-images, or the residual
// threshold R means something else against them).

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/map/map.h"
#include "retrace/repeat/localizer.h"

namespace retrace {

// A map for localizing in: its key-images read from the file on demand (Map::KeyImage; the file stays open while the
// map or a copy of it lives), their size, the camera it stores (null when none), the teach sequence it names, and
// `base` with the tracking settings teach stored in the map (and its camera height, unless `base` has one).
struct MapForLocalizer {
  Map map;
  cv::Size key_image_size;
  std::unique_ptr<CameraModel> camera;
  std::optional<std::string> source_sequence;
  LocalizerOptions options;
};

// Opens and checks the map at `path` (MapDatabase::Open) and reads it. Throws InputError naming the file for a map
// that cannot be used: damaged, without arcs, with a camera that does not image its key-images, or with stored
// tracking settings that fail LocalizerOptions::Check.
MapForLocalizer LoadMapForLocalizer(const std::filesystem::path& path, const LocalizerOptions& base);

class MapDatabase;

// What the metric path fits from the key-images (repeat/taught_path.h), fitted once from the map stored in `database`
// — as repeat reads its key-images — and written to its metadata: the ground's normal in the camera's frame
// ("ground_normal": ground planes between the key-images of 15 arcs spread over the map) and every arc's ground plane
// for that normal ("ground_fits": one line "arc distance_b distance_sigma" per arc, 0 0 where none was found; ≈ 5-8
// ms per arc at 320x240). LoadMapForLocalizer takes them (unless `base` has a normal of its own), so that repeat
// fits nothing: `retrace teach --camera-height`. Returns the normal; none, and nothing stored, when too few arcs
// show a ground. `travel` (may be null) receives the vehicle's travel model over the map (TaughtPath::MapTravelModel),
// for teach to report; it is not stored (repeat fits it around each arc).
std::optional<Vector3d> StoreGroundFits(MapDatabase* database, const CameraModel& camera,
                                        const TaughtPathOptions& options, TravelModel* travel = nullptr);

// The arcs' ground planes of the "ground_fits" metadata text (StoreGroundFits), in the order stored. Throws InputError
// naming `source` for a line that is not "arc distance_b distance_sigma" with a non-negative whole arc id and
// non-negative finite numbers.
std::vector<std::pair<arc_t, MapArc::GroundFit>> ParseGroundFits(const std::string& text, const std::string& source);

}  // namespace retrace
