#include "retrace/exe/key_image_places.h"

#include <system_error>

#include <fmt/format.h>

#include "retrace/dataset/ground_truth.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"

namespace retrace {

KeyImagePlaces ReadKeyImagePlaces(const Map& map, const std::vector<std::filesystem::path>& drives) {
  std::error_code ec;
  std::vector<std::filesystem::path> poses_files;
  KeyImagePlaces places;
  places.town_frame = !drives.empty();
  for (const std::filesystem::path& drive : drives) {
    const std::filesystem::path poses = std::filesystem::is_directory(drive, ec) ? drive / "poses.txt" : drive;
    if (!std::filesystem::is_regular_file(poses, ec)) {
      throw InputError(drive.string(), "has no KITTI ground truth (poses.txt)");
    }
    poses_files.push_back(poses);
    places.town_frame &= std::filesystem::is_regular_file(poses.parent_path() / "scenario.yaml", ec);
  }
  places.x_label = places.town_frame ? "east (m)" : "x (m)";
  places.y_label = places.town_frame ? "north (m)" : "z (m)";

  std::vector<std::vector<Vector2d>> routes;
  for (const std::filesystem::path& poses : poses_files) {
    Rigid3d town_from_world;
    if (places.town_frame) town_from_world = TownFromWorld(ReadScenario((poses.parent_path() / "scenario.yaml").string()));
    std::vector<Vector2d> positions;
    for (const TimedPose& pose : ReadKittiPoses(poses)) {
      const Vector3d c = (town_from_world * pose.world_from_cam).translation;
      positions.push_back(places.town_frame ? Vector2d(c.x(), c.y()) : Vector2d(c.x(), c.z()));
    }
    routes.push_back(std::move(positions));
  }
  for (const MapNode& node : map.nodes()) {
    if (node.route < 0 || node.route >= static_cast<int>(routes.size())) {
      throw InputError(drives.empty() ? std::string("ground truth") : drives.back().string(),
                       fmt::format("the map has route {} (key-image {}) but the ground truth of {} drive(s) was given",
                                   node.route, node.id, routes.size()));
    }
    const std::vector<Vector2d>& route = routes[node.route];
    if (node.source_frame < 0 || node.source_frame >= static_cast<int64_t>(route.size())) {
      throw InputError(poses_files[node.route].string(), fmt::format("has {} poses, but key-image {} is its frame {}",
                                                                     route.size(), node.id, node.source_frame));
    }
    places.positions[node.id] = route[node.source_frame];
  }
  return places;
}

}  // namespace retrace
