// LoadMapForLocalizer takes what teach stored for repeat; here the ground's normal of the metric path
// (StoreGroundNormal): estimated once at teach, the same normal repeat would fit itself, and refused with a clear
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

TEST(MapLoading, GroundNormalStoredAtTeachIsTheOneRepeatWouldFit) {
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
  const std::optional<Vector3d> stored = StoreGroundNormal(database.get(), *drive.camera, options);
  ASSERT_TRUE(stored);
  // The road is below the camera, which is tilted down by a few degrees: the normal points down (+y), slightly
  // forward.
  EXPECT_GT(stored->y(), 0.95);

  // Without it, repeat fits the same normal from the same stored key-images.
  Map read = database->ReadMap(/*load_images=*/false, /*load_signature_features=*/false);
  read.SetKeyImageLoader([&database](node_t id) { return database->ReadKeyImage(id); });
  TaughtPath fitted(read, *drive.camera, options);
  ASSERT_TRUE(fitted.GroundNormal());
  EXPECT_LT((*fitted.GroundNormal() - *stored).norm(), 1e-12);

  // Repeat takes it from the map (and keeps one it is given).
  LocalizerOptions base;
  base.binary_relocalization = false;
  const MapForLocalizer loaded = LoadMapForLocalizer(path, base);
  ASSERT_TRUE(loaded.options.path.ground.normal_in_camera);
  EXPECT_LT((*loaded.options.path.ground.normal_in_camera - *stored).norm(), 1e-8);
  base.path.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  EXPECT_EQ(*LoadMapForLocalizer(path, base).options.path.ground.normal_in_camera, Vector3d(0.0, 1.0, 0.0));
  base.path.ground.normal_in_camera.reset();

  // Damaged text: an error naming the map.
  for (const std::string text : {"0.1 0.9", "0 1 0 0", "0 1 x", "0 2 0"}) {
    database->SetMetadata("ground_normal", text);
    try {
      LoadMapForLocalizer(path, base);
      ADD_FAILURE() << "'" << text << "' accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("ground_normal"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace retrace
