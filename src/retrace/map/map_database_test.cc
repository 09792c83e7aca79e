#include "retrace/map/map_database.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "retrace/map/descriptor_coding.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

cv::Mat RandomImage(int rows, int cols, int seed) {
  cv::Mat image(rows, cols, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

MapNode MakeNode(node_t id, int num_features) {
  MapNode node;
  node.id = id;
  node.source_frame = 10 * id;
  node.image_name = "frame_" + std::to_string(id) + ".png";
  node.timestamp = 0.1 * id;
  node.image = RandomImage(48, 64, static_cast<int>(id));
  for (int i = 0; i < num_features; ++i) {
    FeatureObservation f;
    f.feature_id = 1000 * id + i;
    f.position = Vector2d(1.25 * (i % 40) + 0.5, 0.75 * (i % 50) + 0.125);  // inside the 64x48 key-image
    f.patch = RandomImage(15, 15, static_cast<int>(100 * id + i));
    node.features.push_back(f);
  }
  // A relocalization signature: key-points at 1/8 px positions (stored exactly), random descriptors, a thumbnail.
  for (int i = 0; i < 20; ++i) node.signature.keypoints.emplace_back(0.125f * (17 * i % 500), 0.375f * i, 19.0f + i);
  node.signature.descriptors = RandomImage(20, 32, static_cast<int>(500 + id));
  node.signature.appearance = RandomImage(9, 12, static_cast<int>(700 + id));
  return node;
}

MapArc MakeArc(arc_t id, node_t from, node_t to, int num_points) {
  MapArc arc;
  arc.id = id;
  arc.from = from;
  arc.to = to;
  arc.to_from_from.rotation = Eigen::AngleAxisd(0.1 * (id + 1), Vector3d(0.1, 1.0, 0.2).normalized()).toRotationMatrix();
  arc.to_from_from.translation = Vector3d(0.2, -0.1, 1.0).normalized();
  arc.sigma_p = 1.25 + id;
  for (int i = 0; i < num_points; ++i) arc.points.push_back({1000 * from + i, Vector3d(i, -0.5 * i, 3.0 + i)});
  return arc;
}

TEST(MapDatabase, WriteReadRoundTrip) {
  const auto dir = testing::MakeTempDir("map_roundtrip");
  const auto path = dir / "route.db";
  MapDatabaseOptions options;
  options.image_format = ".png";  // lossless, so images compare exactly
  {
    auto db = MapDatabase::Create(path, options);
    db->SetMetadata("source", "kitti07");
    db->WriteCamera("perspective", 64, 48, "camera_model: perspective\n");
    db->WriteNode(MakeNode(0, 5));
    db->WriteNode(MakeNode(1, 7));
    db->WriteNode(MakeNode(2, 3));
    db->WriteArc(MakeArc(0, 0, 1, 4));
    db->WriteArc(MakeArc(1, 1, 2, 2));
    db->WriteScale({1, 0, 1, 0.75});
  }
  auto db = MapDatabase::Open(path);
  EXPECT_EQ(db->Metadata("source").value_or(""), "kitti07");
  EXPECT_EQ(db->ReadCameraYaml().value_or(""), "camera_model: perspective\n");
  const Map map = db->ReadMap();
  ASSERT_EQ(map.nodes().size(), 3u);
  ASSERT_EQ(map.arcs().size(), 2u);
  for (const MapNode& node : map.nodes()) {
    const MapNode expected = MakeNode(node.id, static_cast<int>(node.features.size()));
    EXPECT_EQ(node.source_frame, expected.source_frame);
    EXPECT_EQ(node.image_name, expected.image_name);
    EXPECT_DOUBLE_EQ(node.timestamp, expected.timestamp);
    EXPECT_EQ(cv::norm(node.image, expected.image, cv::NORM_INF), 0.0);
    for (size_t i = 0; i < node.features.size(); ++i) {
      EXPECT_EQ(node.features[i].feature_id, expected.features[i].feature_id);
      EXPECT_EQ(node.features[i].position, expected.features[i].position);
      EXPECT_EQ(cv::norm(node.features[i].patch, expected.features[i].patch, cv::NORM_INF), 0.0);
    }
  }
  EXPECT_EQ(map.FindNode(1)->features.size(), 7u);
  const MapArc expected = MakeArc(1, 1, 2, 2);
  const MapArc* arc = map.FindArc(1);
  ASSERT_NE(arc, nullptr);
  EXPECT_EQ(arc->from, 1);
  EXPECT_EQ(arc->to, 2);
  EXPECT_TRUE(arc->to_from_from.rotation.isApprox(expected.to_from_from.rotation, 1e-15));
  EXPECT_TRUE(arc->to_from_from.translation.isApprox(expected.to_from_from.translation, 1e-15));
  EXPECT_DOUBLE_EQ(arc->sigma_p, expected.sigma_p);
  ASSERT_EQ(arc->points.size(), 2u);
  EXPECT_EQ(arc->points[1].point_in_from, expected.points[1].point_in_from);
  EXPECT_DOUBLE_EQ(map.ScaleAt(1, 0, 1).value_or(0.0), 0.75);
  EXPECT_EQ(map.ArcsFrom(1).size(), 1u);
  EXPECT_EQ(map.ArcsTo(1).size(), 1u);
  EXPECT_EQ(map.MaxFeatureId(), 2002);  // node 2 has features 2000..2002
}

TEST(MapDatabase, LossyImagesAreSmallerAndClose) {
  const auto dir = testing::MakeTempDir("map_jpg");
  cv::Mat smooth(120, 160, CV_8UC1);
  for (int y = 0; y < smooth.rows; ++y)
    for (int x = 0; x < smooth.cols; ++x) smooth.at<uint8_t>(y, x) = static_cast<uint8_t>(x + y);
  MapNode node = MakeNode(0, 0);
  node.image = smooth;
  {
    auto db = MapDatabase::Create(dir / "route.db");  // default: JPEG
    db->WriteNode(node);
    EXPECT_LT(db->ImageBytes(), static_cast<int64_t>(smooth.total()) / 4);
  }
  const Map map = MapDatabase::Open(dir / "route.db")->ReadMap();
  EXPECT_LT(cv::norm(map.nodes()[0].image, smooth, cv::NORM_L1) / smooth.total(), 1.0);  // mean error, grey levels
}

TEST(MapDatabase, LossyQualityKeepsTheErrorTheTrackerSeesWithinTheBudget) {
  // A textured 1280x384 key-image (kitti07's size, blurred noise) seen by a tracker that smooths by 0.7 px per 320
  // px of width (2.8 px here): a lower quality than 90 keeps the smoothed error within 0.6 grey levels.
  cv::Mat texture = RandomImage(384, 1280, 3);
  cv::GaussianBlur(texture, texture, cv::Size(), 1.5);
  MapNode node = MakeNode(0, 0);
  node.image = texture;
  const auto smoothed_error = [&](const cv::Mat& decoded) {
    cv::Mat a, b;
    texture.convertTo(a, CV_32F);
    decoded.convertTo(b, CV_32F);
    cv::GaussianBlur(a, a, cv::Size(), 2.8, 2.8, cv::BORDER_REFLECT);
    cv::GaussianBlur(b, b, cv::Size(), 2.8, 2.8, cv::BORDER_REFLECT);
    return cv::norm(a, b, cv::NORM_L2) / std::sqrt(static_cast<double>(texture.total()));
  };
  const auto dir = testing::MakeTempDir("map_quality");
  MapDatabaseOptions fixed;
  fixed.max_image_error = 0.0;  // always quality 90
  int64_t fixed_bytes = 0, budget_bytes = 0;
  {
    auto db = MapDatabase::Create(dir / "fixed.db", fixed);
    db->WriteNode(node);
    fixed_bytes = db->ImageBytes();
  }
  {
    auto db = MapDatabase::Create(dir / "budget.db");  // default: 0.6 grey levels
    db->WriteNode(node);
    budget_bytes = db->ImageBytes();
  }
  EXPECT_LT(budget_bytes, fixed_bytes * 3 / 4);
  const Map map = MapDatabase::Open(dir / "budget.db")->ReadMap();
  const double error = smoothed_error(map.nodes()[0].image);
  EXPECT_LE(error, 0.6);
  EXPECT_GT(error, smoothed_error(MapDatabase::Open(dir / "fixed.db")->ReadMap().nodes()[0].image));
  // A budget no quality meets: quality 90, as without one.
  MapDatabaseOptions strict;
  strict.max_image_error = 1e-6;
  {
    auto db = MapDatabase::Create(dir / "strict.db", strict);
    db->WriteNode(node);
    EXPECT_EQ(db->ImageBytes(), fixed_bytes);
  }
  MapDatabaseOptions bad;
  bad.max_image_error = -1.0;
  EXPECT_FALSE(bad.Check());
}

// Expects `f` to throw InputError whose message contains the path and `problem`.
template <typename F>
void ExpectInputError(F&& f, const std::filesystem::path& path, const std::string& problem) {
  try {
    f();
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(MapDatabase, ForeignAndBrokenFilesGiveClearErrors) {
  const auto dir = testing::MakeTempDir("map_foreign");
  ExpectInputError([&] { MapDatabase::Open(dir / "missing.db"); }, dir / "missing.db", "no such map file");

  std::ofstream(dir / "text.db") << "this is not a database\n";
  ExpectInputError([&] { MapDatabase::Open(dir / "text.db"); }, dir / "text.db", "not a retrace map");

  std::ofstream(dir / "empty.db").close();
  ExpectInputError([&] { MapDatabase::Open(dir / "empty.db"); }, dir / "empty.db", "empty file");

  {
    SqliteDatabase other(dir / "other.db", SqliteDatabase::Mode::kCreate);
    other.Execute("CREATE TABLE things (id INTEGER PRIMARY KEY);");
  }
  ExpectInputError([&] { MapDatabase::Open(dir / "other.db"); }, dir / "other.db", "another application");

  MapDatabase::Create(dir / "newer.db").reset();
  {
    SqliteDatabase raw(dir / "newer.db", SqliteDatabase::Mode::kReadWrite);
    raw.Execute("PRAGMA user_version=99;");
  }
  ExpectInputError([&] { MapDatabase::Open(dir / "newer.db"); }, dir / "newer.db", "newer");

  MapDatabase::Create(dir / "exists.db").reset();
  ExpectInputError([&] { MapDatabase::Create(dir / "exists.db"); }, dir / "exists.db", "exists");
  EXPECT_NO_THROW(MapDatabase::Create(dir / "exists.db", {}, /*overwrite=*/true));

  // A truncated map (a crash of the file system, a partial copy) is reported, never read as garbage.
  {
    auto db = MapDatabase::Create(dir / "truncated.db");
    for (int i = 0; i < 20; ++i) db->WriteNode(MakeNode(i, 50));
  }
  std::filesystem::resize_file(dir / "truncated.db", std::filesystem::file_size(dir / "truncated.db") / 2);
  ExpectInputError([&] { MapDatabase::Open(dir / "truncated.db")->ReadMap(); }, dir / "truncated.db",
                   "corrupt map");

  // --overwrite replaces maps only, never another file.
  ExpectInputError([&] { MapDatabase::Create(dir / "text.db", {}, /*overwrite=*/true); }, dir / "text.db",
                   "not a retrace map; refusing to overwrite it");
  ExpectInputError([&] { MapDatabase::Create(dir / "other.db", {}, /*overwrite=*/true); }, dir / "other.db",
                   "not a retrace map; refusing to overwrite it");
  ExpectInputError([&] { MapDatabase::Create(dir, {}, /*overwrite=*/true); }, dir, "not a regular file");
  EXPECT_NO_THROW(MapDatabase::Create(dir / "empty.db", {}, /*overwrite=*/true));  // e.g. made by mktemp
}

// A map of three nodes and two arcs, as teach writes it; `edit` then changes it behind the store's back (raw SQL,
// foreign keys off), and opening it must fail with one printable line naming the file and `problem`.
void ExpectDamagedMapRefused(const std::string& name, const std::string& edit, const std::string& problem) {
  SCOPED_TRACE(name);
  const auto dir = testing::MakeTempDir("map_damaged");
  const auto path = dir / (name + ".db");
  {
    auto db = MapDatabase::Create(path);
    for (int i = 0; i < 3; ++i) db->WriteNode(MakeNode(i, 10));
    db->WriteArc(MakeArc(0, 0, 1, 4));
    db->WriteArc(MakeArc(1, 1, 2, 4));
    db->WriteScale({1, 0, 1, 0.75});
  }
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("PRAGMA foreign_keys=OFF; " + edit);
  }
  try {
    MapDatabase::Open(path)->ReadMap();
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path.string() + ": ", 0), 0u) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << message;
    for (const char c : message) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << message;
  }
}

TEST(MapDatabase, DamagedMapsAreRefusedWithTheFault) {
  ExpectDamagedMapRefused("dangling_arc", "UPDATE arcs SET to_node = 17 WHERE arc_id = 1;",
                          "corrupt map: arc 1 ends at missing node 17");
  ExpectDamagedMapRefused("dangling_from", "UPDATE arcs SET from_node = 9 WHERE arc_id = 0;",
                          "corrupt map: arc 0 starts at missing node 9");
  ExpectDamagedMapRefused("node_deleted", "DELETE FROM nodes WHERE node_id = 2;", "ends at missing node 2");
  ExpectDamagedMapRefused("self_arc", "UPDATE arcs SET to_node = 1 WHERE arc_id = 1;", "leads from node 1 to itself");
  ExpectDamagedMapRefused("orphan_features", "UPDATE node_features SET node_id = 5 WHERE node_id = 2;",
                          "features of missing node 5");
  ExpectDamagedMapRefused("corrupt_features", "UPDATE node_features SET features = zeroblob(40) WHERE node_id = 1;",
                          "corrupt map: features of node 1 are corrupt (checksum mismatch)");
  ExpectDamagedMapRefused("corrupt_points", "UPDATE arc_point_lists SET points = zeroblob(40) WHERE arc_id = 1;",
                          "corrupt map: 3D points of arc 1 are corrupt (checksum mismatch)");
  // Rows of the tables before schema 6 (a map upgraded for `teach --append` keeps them) are checked as before.
  ExpectDamagedMapRefused("row_twice", "INSERT INTO observations VALUES (1, 1003, 1.5, 2.5, 0, NULL);",
                          "feature 1003 of node 1 is stored twice");
  ExpectDamagedMapRefused("orphan_row", "INSERT INTO observations VALUES (6, 1, 1.5, 2.5, 0, NULL);",
                          "features of missing node 6");
  ExpectDamagedMapRefused("orphan_points", "UPDATE arc_point_lists SET arc_id = 4 WHERE arc_id = 1;",
                          "3D points of missing arc 4");
  ExpectDamagedMapRefused("scale_elsewhere", "UPDATE node_scales SET node_id = 2;",
                          "scale at node 2 does not join arc 0 to arc 1 there");
  ExpectDamagedMapRefused("no_table", "DROP TABLE arc_points;", "corrupt map: no table arc_points");
  ExpectDamagedMapRefused("corrupt_image", "UPDATE nodes SET image = CAST(zeroblob(200) AS BLOB) WHERE node_id = 1;",
                          "corrupt map: key-image of node 1 is corrupt (checksum mismatch)");
  ExpectDamagedMapRefused("nan_rotation", "UPDATE arcs SET rotation = zeroblob(72) WHERE arc_id = 0;",
                          "geometry of arc 0 is not a rotation and a unit translation");
  ExpectDamagedMapRefused("feature_outside", "INSERT INTO observations VALUES (1, 99, 1e300, 2.5, 0, NULL);",
                          "lies outside its 64x48 key-image");
  ExpectDamagedMapRefused("corrupt_signature",
                          "UPDATE signatures SET descriptors = zeroblob(640) WHERE node_id = 2;",
                          "corrupt map: relocalization signature of node 2 is corrupt (checksum mismatch)");
  ExpectDamagedMapRefused("orphan_signature", "UPDATE signatures SET node_id = 7 WHERE node_id = 2;",
                          "corrupt map: relocalization signature of missing node 7");
  ExpectDamagedMapRefused("no_signatures", "DROP TABLE signatures;", "corrupt map: no table signatures");
  ExpectDamagedMapRefused("negative_scale", "UPDATE node_scales SET scale = -1;", "is -1");
  ExpectDamagedMapRefused("camera_size", "INSERT INTO cameras VALUES (0, 'perspective', 64, 40, 'yaml');",
                          "key-image of node 0 is 64x48, not the size of the map's camera");
  // A schema whose text was damaged: SQLite quotes it, the message must not.
  ExpectDamagedMapRefused("binary_schema",
                          "PRAGMA writable_schema=ON; UPDATE sqlite_master SET sql = 'CREATE TABLE nodes (' || "
                          "char(1, 10, 200, 27) || ')' WHERE name = 'nodes';",
                          "corrupt map: ");
}

// A map of two key-images (10 features each) joined by one arc (4 points), written as schema 5 wrote it (a row per
// feature and per point), for the tests that downgrade it to an older schema.
void WriteTwoNodeMap(const std::filesystem::path& path) {
  MapDatabase::Create(path);
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("DROP TABLE node_features; DROP TABLE arc_point_lists; PRAGMA user_version=5;");
  }
  auto db = MapDatabase::Open(path, /*writable=*/true);
  for (int i = 0; i < 2; ++i) db->WriteNode(MakeNode(i, 10));
  db->WriteArc(MakeArc(0, 0, 1, 4));
}

// The features and points of WriteTwoNodeMap's map, read back.
void ExpectTwoNodeMapsFeatures(const Map& map) {
  ASSERT_EQ(map.nodes().size(), 2u);
  for (const MapNode& node : map.nodes()) {
    const MapNode written = MakeNode(node.id, 10);
    ASSERT_EQ(node.features.size(), 10u);
    for (size_t i = 0; i < 10; ++i) {
      EXPECT_EQ(node.features[i].feature_id, written.features[i].feature_id);
      EXPECT_EQ(node.features[i].position, written.features[i].position);  // rows keep doubles
    }
  }
  ASSERT_EQ(map.arcs().size(), 1u);
  EXPECT_EQ(map.arcs()[0].points.size(), 4u);
}

TEST(MapDatabase, FeaturesOutsideTheirKeyImageAreRefusedFromBlobsToo) {
  const auto dir = testing::MakeTempDir("map_feature_blob");
  const auto path = dir / "route.db";
  {
    auto db = MapDatabase::Create(path);
    MapNode node = MakeNode(0, 3);
    node.features[1].position.x() = 1e6;  // storable as a float, but not in the 64x48 key-image
    db->WriteNode(node);
    MapNode far = MakeNode(1, 3);
    far.features[0].position.y() = 1e300;  // not storable
    ExpectInputError([&] { db->WriteNode(far); }, path, "features of node 1 cannot be stored");
  }
  ExpectInputError([&] { MapDatabase::Open(path)->ReadMap(); }, path,
                   "corrupt map: feature 1 of node 0 lies outside its 64x48 key-image");
}

TEST(MapDatabase, SignaturesRoundTrip) {
  const auto dir = testing::MakeTempDir("map_signatures");
  const auto path = dir / "route.db";
  std::vector<MapNode> written;
  {
    auto db = MapDatabase::Create(path);
    for (int i = 0; i < 3; ++i) {
      written.push_back(MakeNode(i, 5));
      // Descriptors of 32 bytes (maps before BinaryFeatureOptions::descriptor_bytes) and of 16 (now) both keep
      // their width.
      if (i == 1) written.back().signature.descriptors = written.back().signature.descriptors.colRange(0, 16).clone();
      db->WriteNode(written.back());
    }
    // A key-image without key-points (a blank image) still stores its appearance.
    MapNode blank = MakeNode(3, 0);
    blank.signature.keypoints.clear();
    blank.signature.descriptors = cv::Mat(0, 32, CV_8U);
    db->WriteNode(blank);
    written.push_back(blank);
    db->WriteArc(MakeArc(0, 0, 1, 4));
    EXPECT_EQ(db->SignatureBytes(), 2 * (20 * 6 + 20 * 32 + 9 * 12) + (20 * 6 + 20 * 16 + 9 * 12) + 9 * 12);
    // A descriptor width the matcher cannot take is refused.
    MapNode odd = MakeNode(4, 0);
    odd.signature.descriptors = odd.signature.descriptors.colRange(0, 12).clone();
    EXPECT_THROW(db->WriteNode(odd), std::invalid_argument);
  }
  const Map map = MapDatabase::Open(path)->ReadMap();
  ASSERT_EQ(map.nodes().size(), written.size());
  for (size_t n = 0; n < written.size(); ++n) {
    const KeyImageSignature& a = written[n].signature;
    const KeyImageSignature& b = map.nodes()[n].signature;
    ASSERT_EQ(a.keypoints.size(), b.keypoints.size());
    for (size_t i = 0; i < a.keypoints.size(); ++i) {
      EXPECT_EQ(a.keypoints[i].pt, b.keypoints[i].pt);
      EXPECT_EQ(a.keypoints[i].size, b.keypoints[i].size);
    }
    EXPECT_EQ(b.descriptors.rows, static_cast<int>(a.keypoints.size()));
    if (!a.keypoints.empty()) {
      EXPECT_EQ(b.descriptors.cols, a.descriptors.cols);
      EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_INF), 0.0);
    }
    EXPECT_EQ(cv::norm(a.appearance, b.appearance, cv::NORM_INF), 0.0);
  }
  // Read on demand (repeat's way, issue 16: key-images and key-points stay in the file), they are the same: the map
  // read without them keeps the appearance only, and the loaders give the rest through Map.
  std::shared_ptr<MapDatabase> lazy = MapDatabase::Open(path);
  Map on_demand = lazy->ReadMap(/*load_images=*/false, /*load_signature_features=*/false);
  on_demand.SetKeyImageLoader([lazy](node_t id) { return lazy->ReadKeyImage(id); });
  on_demand.SetSignatureLoader([lazy](node_t id) { return lazy->ReadSignature(id); });
  for (const MapNode& node : map.nodes()) {
    const MapNode& held = *on_demand.FindNode(node.id);
    EXPECT_TRUE(held.image.empty());
    EXPECT_TRUE(held.signature.keypoints.empty() && held.signature.descriptors.empty());
    EXPECT_EQ(cv::norm(held.signature.appearance, node.signature.appearance, cv::NORM_INF), 0.0);
    EXPECT_TRUE(on_demand.HasKeyImage(node.id));
    EXPECT_EQ(cv::norm(on_demand.KeyImage(node.id), node.image, cv::NORM_INF), 0.0);
    const KeyImageSignature read = on_demand.Signature(node.id);
    ASSERT_EQ(read.keypoints.size(), node.signature.keypoints.size());
    for (size_t i = 0; i < read.keypoints.size(); ++i) EXPECT_EQ(read.keypoints[i].pt, node.signature.keypoints[i].pt);
    EXPECT_EQ(read.descriptors.rows, node.signature.descriptors.rows);
    if (!read.keypoints.empty()) {
      EXPECT_EQ(cv::norm(read.descriptors, node.signature.descriptors, cv::NORM_INF), 0.0);
    }
  }
  ExpectInputError([&] { lazy->ReadKeyImage(42); }, path, "node 42 is missing");
  EXPECT_TRUE(lazy->ReadSignature(42).empty());

  // A key-point that cannot be stored is refused with the file named.
  MapNode far = MakeNode(5, 0);
  far.signature.keypoints[0].pt.x = 9000.0f;
  auto db = MapDatabase::Open(path, /*writable=*/true);
  ExpectInputError([&] { db->WriteNode(far); }, path, "cannot be stored");
}

// A stand-in for describing a key-image at its key-points (DescribeBinaryKeyPoints): each descriptor byte is the
// key-image's pixel at the key-point (as stored, 1/8 px) plus the byte's index.
cv::Mat PixelDescriptors(const cv::Mat& image, const std::vector<cv::KeyPoint>& keypoints) {
  cv::Mat descriptors(static_cast<int>(keypoints.size()), 32, CV_8U);
  for (int i = 0; i < descriptors.rows; ++i) {
    const cv::Point at(static_cast<int>(keypoints[i].pt.x), static_cast<int>(keypoints[i].pt.y));
    for (int j = 0; j < 32; ++j) descriptors.at<uint8_t>(i, j) = static_cast<uint8_t>(image.at<uint8_t>(at) + j);
  }
  return descriptors;
}

TEST(MapDatabase, SignaturesStoredAsDifferencesFromTheirKeyImageReadBackExactly) {
  const auto dir = testing::MakeTempDir("map_descriptor_differences");
  const auto path = dir / "route.db";
  // Teach's descriptors: the prediction with two bits flipped in every fourth key-point, and one of another place.
  MapNode node = MakeNode(0, 3);
  MapDatabaseOptions options;
  options.image_format = ".png";  // the key-image read back is the one written
  {
    auto db = MapDatabase::Create(path, options);
    node.signature.descriptors = PixelDescriptors(node.image, node.signature.keypoints);
    for (int i = 0; i < node.signature.descriptors.rows; i += 4) node.signature.descriptors.at<uint8_t>(i, 3) ^= 0x41;
    node.signature.descriptors.row(5).setTo(0x5A);
    db->SetDescriptorPrediction(PixelDescriptors);
    db->WriteNode(node);
    // Without a prediction (teach --verbatim-descriptors) they are stored as they are.
    db->SetDescriptorPrediction(nullptr);
    db->WriteNode(MakeNode(1, 3));
    // 20 key-points: 5 with two bits (3 bytes), 1 itself (33), 14 exact (1), the length byte; and node 1 verbatim.
    EXPECT_EQ(db->SignatureBytes(), (20 * 6 + (1 + 5 * 3 + 33 + 14) + 9 * 12) + (20 * 6 + 20 * 32 + 9 * 12));
  }
  auto db = MapDatabase::Open(path);
  EXPECT_EQ(db->schema_version(), 7);
  const KeyImageSignature read = db->ReadSignature(0);
  EXPECT_TRUE(read.descriptors.empty());
  ASSERT_FALSE(read.descriptor_residual.empty());
  cv::Mat descriptors;
  ASSERT_FALSE(DecodeDescriptorResidual(read.descriptor_residual, PixelDescriptors(db->ReadKeyImage(0), read.keypoints),
                                        &descriptors));
  EXPECT_EQ(cv::norm(descriptors, node.signature.descriptors, cv::NORM_HAMMING), 0.0);
  // ReadMap keeps them as differences too; node 1's are as written.
  const Map map = db->ReadMap();
  EXPECT_FALSE(map.FindNode(0)->signature.descriptor_residual.empty());
  EXPECT_EQ(map.FindNode(1)->signature.descriptors.rows, 20);
  EXPECT_TRUE(map.FindNode(1)->signature.descriptor_residual.empty());
  // An unknown coding (the checksum covers the blobs, not this column) is refused with the map and node named.
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("UPDATE signatures SET descriptor_coding = 2 WHERE node_id = 0;");
  }
  ExpectInputError([&] { MapDatabase::Open(path)->ReadSignature(0); }, path, "unknown descriptor coding 2");
}

TEST(MapDatabase, MapsOfSchemaSixAreUpgradedWithTheirSignaturesVerbatim) {
  const auto dir = testing::MakeTempDir("map_schema6");
  const auto path = dir / "old.db";
  const MapNode node = MakeNode(0, 3);
  {
    auto db = MapDatabase::Create(path);
    db->WriteNode(node);
  }
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("ALTER TABLE signatures DROP COLUMN descriptor_coding; PRAGMA user_version=6;");
  }
  EXPECT_EQ(MapDatabase::Open(path)->ReadSignature(0).descriptors.rows, 20);
  auto db = MapDatabase::Open(path, /*writable=*/true);
  db->UpgradeSchema();
  EXPECT_EQ(db->schema_version(), 7);
  const KeyImageSignature read = db->ReadSignature(0);
  EXPECT_TRUE(read.descriptor_residual.empty());
  EXPECT_EQ(cv::norm(read.descriptors, node.signature.descriptors, cv::NORM_HAMMING), 0.0);
}

TEST(MapDatabase, MapsOfSchemaThreeAreReadWithoutSignatures) {
  const auto dir = testing::MakeTempDir("map_schema3");
  const auto path = dir / "old.db";
  WriteTwoNodeMap(path);
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("DROP TABLE signatures; PRAGMA user_version=3;");
  }
  auto db = MapDatabase::Open(path);
  EXPECT_EQ(db->schema_version(), 3);
  EXPECT_EQ(db->SignatureBytes(), 0);
  const Map map = db->ReadMap();
  ExpectTwoNodeMapsFeatures(map);
  for (const MapNode& node : map.nodes()) EXPECT_TRUE(node.signature.empty());
}

TEST(MapDatabase, MapsOfSchemaOneAreRead) {
  const auto dir = testing::MakeTempDir("map_schema1");
  const auto path = dir / "old.db";
  WriteTwoNodeMap(path);
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("DROP TABLE signatures; ALTER TABLE nodes DROP COLUMN image_crc32; PRAGMA user_version=1;");
  }
  ExpectTwoNodeMapsFeatures(MapDatabase::Open(path)->ReadMap());
  // Without checksums a truncated JPEG is still found by its missing end.
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("UPDATE nodes SET image = substr(image, 1, length(image) - 10) WHERE node_id = 1;");
  }
  ExpectInputError([&] { MapDatabase::Open(path); }, path, "key-image of node 1 is corrupt (not a whole JPEG");
}

TEST(MapDatabase, RoutesAndSimilaritiesRoundTrip) {
  const auto dir = testing::MakeTempDir("map_routes");
  const auto path = dir / "graph.db";
  {
    auto db = MapDatabase::Create(path);
    for (int i = 0; i < 3; ++i) {
      MapNode node = MakeNode(i, 4);
      node.route = i == 2 ? 1 : 0;
      db->WriteNode(node);
    }
    MapArc tracked = MakeArc(0, 0, 1, 4);
    tracked.similarity = 0.375;
    MapArc join = MakeArc(1, 2, 1, 2);
    join.kind = "join";
    join.similarity = 0.0625;
    db->WriteArc(tracked);
    db->WriteArc(join);
    db->WriteArc(MakeArc(2, 1, 2, 2));  // similarity unknown
  }
  const Map map = MapDatabase::Open(path)->ReadMap(false);
  EXPECT_EQ(map.FindNode(0)->route, 0);
  EXPECT_EQ(map.FindNode(2)->route, 1);
  EXPECT_DOUBLE_EQ(map.FindArc(0)->similarity.value_or(-1), 0.375);
  EXPECT_EQ(map.FindArc(1)->kind, "join");
  EXPECT_DOUBLE_EQ(map.FindArc(1)->similarity.value_or(-1), 0.0625);
  EXPECT_FALSE(map.FindArc(2)->similarity.has_value());
  // A similarity outside [0, 1] is a damaged map.
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("UPDATE arcs SET similarity = 7 WHERE arc_id = 1;");
  }
  ExpectInputError([&] { MapDatabase::Open(path)->ReadMap(false); }, path, "similarity of arc 1 is 7, not in [0, 1]");
}

TEST(MapDatabase, MapsOfSchemaTwoHaveRouteZeroAndUnknownSimilarity) {
  const auto dir = testing::MakeTempDir("map_schema2");
  const auto path = dir / "old.db";
  WriteTwoNodeMap(path);
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute(
        "DROP TABLE signatures; ALTER TABLE nodes DROP COLUMN route; ALTER TABLE arcs DROP COLUMN similarity; "
        "PRAGMA user_version=2;");
  }
  const Map map = MapDatabase::Open(path)->ReadMap();
  ASSERT_EQ(map.nodes().size(), 2u);
  EXPECT_EQ(map.nodes()[1].route, 0);
  EXPECT_FALSE(map.arcs()[0].similarity.has_value());
}

// teach --append on a map of schema 1: the copy is upgraded (checksums, routes, similarities), the map itself stays
// byte-identical until the append is committed.
TEST(StagedMap, AppendUpgradesACopyAndReplacesTheMapOnlyOnCommit) {
  const auto dir = testing::MakeTempDir("map_append");
  const auto path = dir / "old.db";
  WriteTwoNodeMap(path);
  {
    SqliteDatabase raw(path, SqliteDatabase::Mode::kReadWrite);
    raw.Execute("DROP TABLE signatures; ALTER TABLE nodes DROP COLUMN image_crc32; ALTER TABLE nodes DROP COLUMN "
                "route; ALTER TABLE arcs DROP COLUMN similarity; PRAGMA user_version=1;");
  }
  const auto read_bytes = [](const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string before = read_bytes(path);
  {
    auto staged = StagedMap::BeginAppend(path);
    EXPECT_EQ(staged->database()->schema_version(), MapDatabase::kSchemaVersion);
    MapNode node = MakeNode(2, 3);
    node.route = 1;
    staged->database()->WriteNode(node);
    // Not committed: the map is unchanged.
  }
  EXPECT_EQ(read_bytes(path), before);
  {
    auto staged = StagedMap::BeginAppend(path);
    MapNode node = MakeNode(2, 3);
    node.route = 1;
    staged->database()->WriteNode(node);
    MapArc join = MakeArc(1, 2, 1, 2);
    join.kind = "join";
    join.similarity = 0.125;
    staged->database()->WriteArc(join);
    staged->Commit();
  }
  EXPECT_FALSE(std::filesystem::exists(StagedMap::StagingPathFor(path)));
  auto db = MapDatabase::Open(path);  // every key-image checksum verified
  EXPECT_EQ(db->schema_version(), MapDatabase::kSchemaVersion);
  const Map map = db->ReadMap();
  ASSERT_EQ(map.nodes().size(), 3u);
  EXPECT_EQ(map.FindNode(0)->route, 0);
  EXPECT_EQ(map.FindNode(2)->route, 1);
  EXPECT_FALSE(map.FindArc(0)->similarity.has_value());
  EXPECT_DOUBLE_EQ(map.FindArc(1)->similarity.value_or(-1), 0.125);
  // The upgrade added the signatures table: the appended key-image keeps its signature, the old ones have none.
  EXPECT_FALSE(map.FindNode(2)->signature.empty());
  EXPECT_TRUE(map.FindNode(0)->signature.empty());
  // The old key-images' features and arc's points stay in their rows, the appended ones are in blobs (schema 6):
  // both are read.
  EXPECT_EQ(map.FindNode(0)->features.size(), 10u);
  EXPECT_EQ(map.FindNode(2)->features.size(), 3u);
  EXPECT_EQ(map.FindArc(0)->points.size(), 4u);
  EXPECT_EQ(map.FindArc(1)->points.size(), 2u);
  {
    auto raw = MapDatabase::Open(path, /*writable=*/true);
    // Features found later are added to a key-image's blob.
    raw->WriteObservations(2, {MakeNode(9, 2).features});
  }
  EXPECT_EQ(MapDatabase::Open(path)->ReadMap().FindNode(2)->features.size(), 5u);
  {
    // A feature of an old key-image's rows, or of a blob, is not stored twice: refused when written, the map stays
    // readable.
    auto raw = MapDatabase::Open(path, /*writable=*/true);
    ExpectInputError([&] { raw->WriteObservations(0, {MakeNode(0, 2).features[1]}); }, path,
                     "features of node 0 cannot be stored: feature 1 is stored already");
    ExpectInputError([&] { raw->WriteObservations(2, {MakeNode(2, 1).features[0]}); }, path,
                     "features of node 2 cannot be stored: EncodeFeatures: feature 2000 appears twice");
  }
  EXPECT_EQ(MapDatabase::Open(path)->ReadMap().FindNode(0)->features.size(), 10u);
  // A missing map cannot be appended to.
  ExpectInputError([&] { StagedMap::BeginAppend(dir / "missing.db"); }, dir / "missing.db", "no such map");
  // Nor an incomplete one.
  {
    auto db = MapDatabase::Open(path, /*writable=*/true);
    db->SetMetadata(MapDatabase::kTeachStateKey, MapDatabase::kIncomplete);
  }
  ExpectInputError([&] { StagedMap::BeginAppend(path); }, path, "incomplete map (its teach did not finish)");
}

TEST(StagedMap, TheOldMapIsReplacedOnlyByACommittedOne) {
  const auto dir = testing::MakeTempDir("map_staged");
  const auto path = dir / "route.db";
  {
    auto staged = StagedMap::Begin(path);
    staged->database()->WriteNode(MakeNode(0, 5));
    EXPECT_TRUE(std::filesystem::exists(dir / "route.db.incomplete"));
    EXPECT_TRUE(std::filesystem::exists(dir / "route.db.lock"));
    EXPECT_FALSE(std::filesystem::exists(path));
    staged->Commit();
  }
  const auto old_size = std::filesystem::file_size(path);
  for (const char* left : {".incomplete", ".lock", "-wal", "-shm", "-journal", ".incomplete-wal"}) {
    EXPECT_FALSE(std::filesystem::exists(path.string() + left)) << left;
  }
  EXPECT_TRUE(MapDatabase::Open(path)->complete());

  // Without --overwrite an existing map is refused at once; with it, a failed teach leaves the old map alone.
  ExpectInputError([&] { StagedMap::Begin(path); }, path, "exists already");
  {
    auto staged = StagedMap::Begin(path, {}, /*overwrite=*/true);
    for (int i = 0; i < 3; ++i) staged->database()->WriteNode(MakeNode(i, 5));
    // A second writer of the same path is refused while the first writes.
    ExpectInputError([&] { StagedMap::Begin(path, {}, true); }, path, "another retrace teach is writing this map");
  }  // destroyed without Commit: an error in teach
  EXPECT_EQ(std::filesystem::file_size(path), old_size);
  EXPECT_EQ(MapDatabase::Open(path)->NumNodes(), 1);
  auto left = MapDatabase::Open(dir / "route.db.incomplete");
  EXPECT_FALSE(left->complete());
  EXPECT_EQ(left->NumNodes(), 3);
  left.reset();
  EXPECT_FALSE(std::filesystem::exists(dir / "route.db.lock"));

  // The next teach replaces the stale staging map and then the old map.
  {
    auto staged = StagedMap::Begin(path, {}, /*overwrite=*/true);
    for (int i = 0; i < 2; ++i) staged->database()->WriteNode(MakeNode(i, 5));
    staged->Commit();
  }
  EXPECT_EQ(MapDatabase::Open(path)->NumNodes(), 2);
  EXPECT_FALSE(std::filesystem::exists(dir / "route.db.incomplete"));

  // A file that is not a map is never replaced.
  std::ofstream(dir / "notes.txt") << "not a map\n";
  ExpectInputError([&] { StagedMap::Begin(dir / "notes.txt", {}, true); }, dir / "notes.txt",
                   "not a retrace map; refusing to overwrite it");
  EXPECT_FALSE(std::filesystem::exists(dir / "notes.txt.incomplete"));
}

TEST(MapDatabase, ReadOnlyMapRefusesWrites) {
  const auto dir = testing::MakeTempDir("map_readonly");
  MapDatabase::Create(dir / "route.db").reset();
  auto db = MapDatabase::Open(dir / "route.db", /*writable=*/false);
  ExpectInputError([&] { db->WriteNode(MakeNode(0, 1)); }, dir / "route.db", "read-only");
}

TEST(MapDatabase, KilledWriterLeavesEveryCommittedKeyImage) {
  const auto dir = testing::MakeTempDir("map_kill");
  const auto path = dir / "route.db";
  constexpr int kCommitted = 7;
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The child writes key-images the way teach does (node + arc in one transaction) and is killed in the middle
    // of the next transaction, without any chance to clean up.
    auto db = MapDatabase::Create(path);
    for (int i = 0; i < kCommitted; ++i) {
      auto transaction = db->BeginTransaction();
      db->WriteNode(MakeNode(i, 40));
      if (i > 0) db->WriteArc(MakeArc(i - 1, i - 1, i, 20));
      transaction->Commit();
    }
    auto transaction = db->BeginTransaction();
    db->WriteNode(MakeNode(kCommitted, 40));
    kill(getpid(), SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  auto db = MapDatabase::Open(path);
  const Map map = db->ReadMap();
  EXPECT_EQ(map.nodes().size(), static_cast<size_t>(kCommitted));
  EXPECT_EQ(map.arcs().size(), static_cast<size_t>(kCommitted - 1));
  EXPECT_EQ(map.nodes().back().features.size(), 40u);
}

TEST(StagedMap, KilledWriterLeavesAnIncompleteMapAndTheOldOneUntouched) {
  const auto dir = testing::MakeTempDir("map_staged_kill");
  const auto path = dir / "route.db";
  {
    auto staged = StagedMap::Begin(path);
    staged->database()->WriteNode(MakeNode(0, 5));
    staged->Commit();
  }
  const auto old_size = std::filesystem::file_size(path);
  constexpr int kCommitted = 5;
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto staged = StagedMap::Begin(path, {}, /*overwrite=*/true);
    MapDatabase* db = staged->database();
    for (int i = 0; i < kCommitted; ++i) {
      auto transaction = db->BeginTransaction();
      db->WriteNode(MakeNode(i, 40));
      if (i > 0) db->WriteArc(MakeArc(i - 1, i - 1, i, 20));
      transaction->Commit();
    }
    auto transaction = db->BeginTransaction();
    db->WriteNode(MakeNode(kCommitted, 40));
    kill(getpid(), SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  // The killed writer's file is marked as a map in the file itself, not only in its log.
  EXPECT_NO_THROW(MapDatabase::CheckReplaceable(dir / "route.db.incomplete"));
  EXPECT_EQ(std::filesystem::file_size(path), old_size);
  EXPECT_EQ(MapDatabase::Open(path)->NumNodes(), 1);
  auto left = MapDatabase::Open(dir / "route.db.incomplete");
  EXPECT_FALSE(left->complete());
  const Map map = left->ReadMap();
  EXPECT_EQ(map.nodes().size(), static_cast<size_t>(kCommitted));
  EXPECT_EQ(map.arcs().size(), static_cast<size_t>(kCommitted - 1));
  left.reset();
  // The killed writer's lock is released with it: the next writer goes ahead and replaces the staging map.
  EXPECT_NO_THROW(StagedMap::Begin(path, {}, /*overwrite=*/true)->Commit());
}

}  // namespace
// The smoothed error of `decoded` against `original` as the tracker sees it (MapDatabaseOptions::max_image_error)
// and the shift between the two (phase correlation), with the tracker's smoothing of `sigma` pixels.
std::pair<double, cv::Point2d> SmoothedErrorAndShift(const cv::Mat& original, const cv::Mat& decoded, double sigma) {
  cv::Mat a, b;
  original.convertTo(a, CV_64F);
  decoded.convertTo(b, CV_64F);
  cv::GaussianBlur(a, a, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  cv::GaussianBlur(b, b, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  const double error = cv::norm(a, b, cv::NORM_L2) / std::sqrt(static_cast<double>(a.total()));
  return {error, cv::phaseCorrelate(a, b)};
}

TEST(MapDatabase, LargeKeyImagesAreStoredAtAReducedResolutionWithinTheBudget) {
  // A 1241x376 key-image (a side not divisible by 2 or 3) whose texture is as coarse as what the tracker keeps of a
  // kitti07 frame after its 2.7 px smoothing: stored smaller than at full resolution with the same error budget,
  // read back at its size, within the budget and not shifted.
  cv::Mat texture = RandomImage(376, 1241, 5);
  cv::GaussianBlur(texture, texture, cv::Size(), 2.0);
  cv::normalize(texture, texture, 0, 255, cv::NORM_MINMAX);
  MapNode node = MakeNode(0, 0);
  node.image = texture;
  const auto dir = testing::MakeTempDir("map_downscale");
  MapDatabaseOptions full;
  full.max_image_downscale = 1;
  int64_t full_bytes = 0, reduced_bytes = 0;
  {
    auto db = MapDatabase::Create(dir / "full.db", full);
    db->WriteNode(node);
    full_bytes = db->ImageBytes();
  }
  {
    auto db = MapDatabase::Create(dir / "reduced.db");  // default: down to 1/4
    db->WriteNode(node);
    reduced_bytes = db->ImageBytes();
  }
  EXPECT_LT(reduced_bytes, full_bytes * 2 / 3);
  const double sigma = 0.7 * 1241 / 320;
  const cv::Mat read = MapDatabase::Open(dir / "reduced.db")->ReadMap().nodes()[0].image;
  ASSERT_EQ(read.size(), texture.size());
  const auto [error, shift] = SmoothedErrorAndShift(texture, read, sigma);
  EXPECT_LE(error, 0.6);
  EXPECT_LT(std::hypot(shift.x, shift.y), 0.02);
  EXPECT_EQ(MapDatabase::Open(dir / "reduced.db")->ReadKeyImage(0).size(), texture.size());

  // A 320x240 key-image with detail at the scale of its 0.7 px smoothing keeps its resolution.
  cv::Mat fine = RandomImage(240, 320, 6);
  cv::GaussianBlur(fine, fine, cv::Size(), 0.8);
  node.image = fine;
  {
    auto a = MapDatabase::Create(dir / "fine_full.db", full);
    a->WriteNode(node);
    auto b = MapDatabase::Create(dir / "fine.db");
    b->WriteNode(node);
    EXPECT_EQ(b->ImageBytes(), a->ImageBytes());
  }

  // A map of schema 4 opened for writing keeps full resolutions (retraces of that schema read it).
  node.image = texture;
  WriteTwoNodeMap(dir / "old.db");
  {
    SqliteDatabase raw(dir / "old.db", SqliteDatabase::Mode::kReadWrite);
    raw.Execute("PRAGMA user_version=4;");
  }
  {
    auto db = MapDatabase::Open(dir / "old.db", /*writable=*/true);
    const int64_t before = db->ImageBytes();
    node.id = 7;
    db->WriteNode(node);
    EXPECT_EQ(db->ImageBytes() - before, full_bytes);
  }
  // A stored image of another size than its node's (not a whole reduction) is refused with what is wrong.
  {
    SqliteDatabase raw(dir / "reduced.db", SqliteDatabase::Mode::kReadWrite);
    raw.Execute("UPDATE nodes SET width = 1200;");
  }
  ExpectInputError([&] { MapDatabase::Open(dir / "reduced.db")->ReadMap(); }, dir / "reduced.db",
                   "is 621x188 but is stored as 1200x376");
  MapDatabaseOptions bad;
  bad.max_image_downscale = 0;
  EXPECT_FALSE(bad.Check());
}

}  // namespace retrace
