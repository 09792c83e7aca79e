// LoadMapForLocalizer takes what teach stored for repeat; here the metric path's ground normal and the arcs' ground
// planes (StoreGroundFits): fitted once at teach, the same as repeat would fit itself, and refused with a clear
// error when the stored text is damaged.

#include "retrace/repeat/map_loading.h"

#include <gtest/gtest.h>

#include "retrace/map/map_database.h"
#include "retrace/repeat/taught_path.h"
#include "retrace/sim/recording.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

TEST(MapLoading, GroundFitsStoredAtTeachAreTheOnesRepeatWouldFit) {
  Scenario scenario;
  scenario.num_frames = 80;
  const RecordedDrive drive = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  Teacher teacher(*drive.camera, TeachOptions(), nullptr);
  for (const Frame& frame : drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  ASSERT_GE(teacher.map().arcs().size(), 5u);

  const auto path = testing::MakeTempDir("map_loading_ground_normal") / "town.db";
  auto database = MapDatabase::Create(path);
  for (const MapNode& node : teacher.map().nodes()) database->WriteNode(node);
  for (const MapArc& arc : teacher.map().arcs()) database->WriteArc(arc);
  for (const NodeScale& scale : teacher.map().scales()) database->WriteScale(scale);
  TaughtPathOptions options;
  options.camera_height = scenario.vehicle.camera_height;
  const std::optional<Vector3d> stored = StoreGroundFits(database.get(), *drive.camera, options);
  ASSERT_TRUE(stored);
  // The road is below the camera, which is tilted down by a few degrees: the normal points down (+y), slightly
  // forward.
  EXPECT_GT(stored->y(), 0.95);

  // Without them, repeat fits the same normal and the same planes from the same stored key-images.
  Map read = database->ReadMap(/*load_images=*/false, /*load_signature_features=*/false);
  read.SetKeyImageLoader([&database](node_t id) { return database->ReadKeyImage(id); });
  TaughtPath fitted(read, *drive.camera, options);
  ASSERT_TRUE(fitted.GroundNormal());
  EXPECT_EQ(*fitted.GroundNormal(), *stored);

  // Repeat takes them from the map: the metric path's scales exactly as fitted, without a key-image read.
  LocalizerOptions base;
  base.binary_relocalization = false;
  const MapForLocalizer loaded = LoadMapForLocalizer(path, base);
  ASSERT_TRUE(loaded.options.path.ground.normal_in_camera);
  EXPECT_EQ(*loaded.options.path.ground.normal_in_camera, *stored);
  Map without_images = loaded.map;
  without_images.SetKeyImageLoader([](node_t) -> cv::Mat { throw std::logic_error("a key-image was read"); });
  TaughtPathOptions from_map = options;
  from_map.ground.normal_in_camera = loaded.options.path.ground.normal_in_camera;
  TaughtPath taken(without_images, *drive.camera, from_map);
  int valid = 0;
  for (const MapArc& arc : loaded.map.arcs()) {
    ASSERT_TRUE(arc.ground_fit) << "arc " << arc.id;
    EXPECT_EQ(arc.ground_fit->distance_b, fitted.GroundFit(arc.id).distance_b) << "arc " << arc.id;
    EXPECT_EQ(arc.ground_fit->distance_sigma, fitted.GroundFit(arc.id).distance_sigma) << "arc " << arc.id;
    valid += arc.ground_fit->distance_b > 0;
    EXPECT_EQ(taken.MetresPerUnit(arc.id), fitted.MetresPerUnit(arc.id)) << "arc " << arc.id;
  }
  EXPECT_GE(valid, static_cast<int>(loaded.map.arcs().size()) - 1);
  // A normal repeat is given replaces the map's, and the planes fitted for the map's are not taken.
  base.path.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  const MapForLocalizer other = LoadMapForLocalizer(path, base);
  EXPECT_EQ(*other.options.path.ground.normal_in_camera, Vector3d(0.0, 1.0, 0.0));
  EXPECT_FALSE(other.map.arcs().front().ground_fit);
  base.path.ground.normal_in_camera.reset();

  // Damaged text: an error naming the map and the entry.
  const auto expect_refused = [&](const std::string& key, const std::string& text) {
    try {
      LoadMapForLocalizer(path, base);
      ADD_FAILURE() << key << " '" << text << "' accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  const std::string normal = *database->Metadata("ground_normal");
  for (const std::string text : {"0.1 0.9", "0 1 0 0", "0 1 x", "0 2 0"}) {
    database->SetMetadata("ground_normal", text);
    expect_refused("ground_normal", text);
  }
  database->SetMetadata("ground_normal", normal);
  for (const std::string text : {"0 0.3", "0 0.3 0.01 7", "9999 0.3 0.01", "-1 0.3 0.01", "0 -0.3 0.01", "0 nan 0"}) {
    database->SetMetadata("ground_fits", text + "\n");
    expect_refused("ground_fits", text);
  }
}

}  // namespace
}  // namespace retrace
