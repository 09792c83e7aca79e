#include "retrace/map/map_database.h"

#include <unistd.h>

#include <opencv2/imgcodecs.hpp>

#include "retrace/util/error.h"
#include "retrace/util/version.h"

namespace retrace {
namespace {

std::vector<uint8_t> EncodeImage(const cv::Mat& image, const MapDatabaseOptions& options, const std::string& source) {
  std::vector<int> params;
  if (options.image_format == ".jpg") params = {cv::IMWRITE_JPEG_QUALITY, options.image_quality};
  if (options.image_format == ".webp") params = {cv::IMWRITE_WEBP_QUALITY, options.image_quality};
  std::vector<uint8_t> bytes;
  if (!cv::imencode(options.image_format, image, bytes, params)) {
    throw InputError(source, "cannot encode key-image as " + options.image_format);
  }
  return bytes;
}

template <int N>
std::vector<double> ToDoubles(const Eigen::Matrix<double, N, 1>& v) {
  return std::vector<double>(v.data(), v.data() + N);
}

}  // namespace

bool MapDatabaseOptions::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (image_format != ".png" && image_format != ".jpg" && image_format != ".webp") {
    return fail("image_format must be .png, .jpg or .webp, not '" + image_format + "'");
  }
  if (image_quality < 1 || image_quality > 100) return fail("image_quality must be in 1..100");
  return true;
}

MapDatabase::MapDatabase(const std::filesystem::path& path, SqliteDatabase::Mode mode,
                         const MapDatabaseOptions& options)
    : path_(path),
      options_(options),
      database_(std::make_unique<SqliteDatabase>(path, mode)),
      writable_(mode != SqliteDatabase::Mode::kReadOnly) {}

MapDatabase::~MapDatabase() {
  if (!writable_) return;
  try {
    // Fold the write-ahead log back into the map file so the map is one self-contained file.
    database_->Execute("PRAGMA wal_checkpoint(TRUNCATE); PRAGMA journal_mode=DELETE;");
  } catch (...) {
    // The WAL file stays beside the map; SQLite folds it in on the next open.
  }
}

std::unique_ptr<MapDatabase> MapDatabase::Create(const std::filesystem::path& path,
                                                 const MapDatabaseOptions& options, bool overwrite) {
  std::string error;
  if (!options.Check(&error)) throw InputError(path.string(), "bad map options: " + error);
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    if (!overwrite) throw InputError(path.string(), "map file exists already (choose another name or overwrite)");
    std::filesystem::remove(path, ec);
    for (const char* suffix : {"-wal", "-shm", "-journal"}) std::filesystem::remove(path.string() + suffix, ec);
    if (std::filesystem::exists(path)) throw InputError(path.string(), "cannot replace the existing file");
  }
  std::unique_ptr<MapDatabase> map(new MapDatabase(path, SqliteDatabase::Mode::kCreate, options));
  map->database_->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL; PRAGMA foreign_keys=ON;");
  map->database_->Execute("PRAGMA application_id=" + std::to_string(kApplicationId) + ";");
  map->database_->Execute("PRAGMA user_version=" + std::to_string(kSchemaVersion) + ";");
  map->CreateTables();
  map->SetMetadata("retrace_version", Version());
  map->SetMetadata("image_format", options.image_format);
  return map;
}

std::unique_ptr<MapDatabase> MapDatabase::Open(const std::filesystem::path& path, bool writable) {
  // A map killed during teach has its last transactions in the -wal file; recovering them needs write access,
  // so open read-write whenever the file allows it, even to read.
  const bool can_write = access(path.c_str(), W_OK) == 0;
  const auto mode = (writable || can_write) ? SqliteDatabase::Mode::kReadWrite : SqliteDatabase::Mode::kReadOnly;
  if (writable && !can_write) throw InputError(path.string(), "map file is not writable");
  std::unique_ptr<MapDatabase> map(new MapDatabase(path, mode, MapDatabaseOptions()));
  map->writable_ = writable;
  map->CheckIsRetraceMap();
  map->database_->Execute("PRAGMA foreign_keys=ON;");
  if (const auto format = map->Metadata("image_format")) map->options_.image_format = *format;
  return map;
}

void MapDatabase::CheckIsRetraceMap() {
  const std::string source = path_.string();
  std::error_code ec;
  if (std::filesystem::file_size(path_, ec) == 0) throw InputError(source, "not a retrace map (empty file)");
  // Reading a pragma is the first access to the file: SQLite reports a foreign file here (SQLITE_NOTADB).
  const int64_t application_id = database_->PragmaInt("application_id");
  if (application_id != kApplicationId) {
    throw InputError(source, "not a retrace map (an SQLite database of another application)");
  }
  const int64_t version = database_->PragmaInt("user_version");
  if (version > kSchemaVersion) {
    throw InputError(source, "map schema version " + std::to_string(version) +
                                 " is newer than this retrace supports (" + std::to_string(kSchemaVersion) +
                                 "); update retrace");
  }
  if (version < 1) throw InputError(source, "not a retrace map (no schema version)");
}

void MapDatabase::CreateTables() {
  database_->Execute(R"sql(
    CREATE TABLE IF NOT EXISTS metadata (
      key TEXT PRIMARY KEY NOT NULL,
      value TEXT NOT NULL);
    CREATE TABLE IF NOT EXISTS cameras (
      camera_id INTEGER PRIMARY KEY NOT NULL,
      model TEXT NOT NULL,
      width INTEGER NOT NULL,
      height INTEGER NOT NULL,
      yaml TEXT NOT NULL);
    CREATE TABLE IF NOT EXISTS nodes (
      node_id INTEGER PRIMARY KEY NOT NULL,
      source_frame INTEGER NOT NULL,
      image_name TEXT NOT NULL,
      timestamp REAL NOT NULL,
      width INTEGER NOT NULL,
      height INTEGER NOT NULL,
      image BLOB);
    CREATE TABLE IF NOT EXISTS observations (
      node_id INTEGER NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      feature_id INTEGER NOT NULL,
      x REAL NOT NULL,
      y REAL NOT NULL,
      patch_size INTEGER NOT NULL,
      patch BLOB,
      PRIMARY KEY (node_id, feature_id)) WITHOUT ROWID;
    CREATE TABLE IF NOT EXISTS arcs (
      arc_id INTEGER PRIMARY KEY NOT NULL,
      from_node INTEGER NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      to_node INTEGER NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      kind TEXT NOT NULL,
      rotation BLOB NOT NULL,
      translation BLOB NOT NULL,
      sigma_p REAL NOT NULL,
      num_features INTEGER NOT NULL);
    CREATE TABLE IF NOT EXISTS arc_points (
      arc_id INTEGER NOT NULL REFERENCES arcs(arc_id) ON DELETE CASCADE,
      feature_id INTEGER NOT NULL,
      x REAL NOT NULL,
      y REAL NOT NULL,
      z REAL NOT NULL,
      PRIMARY KEY (arc_id, feature_id)) WITHOUT ROWID;
    CREATE TABLE IF NOT EXISTS node_scales (
      node_id INTEGER NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      arc_in INTEGER NOT NULL REFERENCES arcs(arc_id) ON DELETE CASCADE,
      arc_out INTEGER NOT NULL REFERENCES arcs(arc_id) ON DELETE CASCADE,
      scale REAL NOT NULL,
      PRIMARY KEY (node_id, arc_in, arc_out)) WITHOUT ROWID;
  )sql");
}

template <typename Writer>
void MapDatabase::InTransaction(Writer&& writer) {
  if (!writable_) throw InputError(path_.string(), "map is open read-only");
  if (sqlite3_get_autocommit(database_->handle()) == 0) {  // the caller holds a transaction
    writer();
    return;
  }
  SqliteTransaction transaction(database_.get());
  writer();
  transaction.Commit();
}

std::unique_ptr<SqliteTransaction> MapDatabase::BeginTransaction() {
  return std::make_unique<SqliteTransaction>(database_.get());
}

void MapDatabase::SetMetadata(const std::string& key, const std::string& value) {
  InTransaction([&] {
    database_->Prepare("INSERT OR REPLACE INTO metadata (key, value) VALUES (?, ?);").Bind(1, key).Bind(2, value).Run();
  });
}

std::optional<std::string> MapDatabase::Metadata(const std::string& key) {
  SqliteStatement& s = database_->Prepare("SELECT value FROM metadata WHERE key = ?;");
  s.Bind(1, key);
  std::optional<std::string> value;
  if (s.Step()) value = s.ColumnText(0);
  s.Reset();
  return value;
}

std::map<std::string, std::string> MapDatabase::AllMetadata() {
  std::map<std::string, std::string> result;
  SqliteStatement& s = database_->Prepare("SELECT key, value FROM metadata ORDER BY key;");
  while (s.Step()) result[s.ColumnText(0)] = s.ColumnText(1);
  s.Reset();
  return result;
}

void MapDatabase::WriteCamera(const std::string& model, int width, int height, const std::string& yaml) {
  InTransaction([&] {
    database_->Prepare("INSERT OR REPLACE INTO cameras (camera_id, model, width, height, yaml) VALUES (0, ?, ?, ?, ?);")
        .Bind(1, model)
        .Bind(2, int64_t{width})
        .Bind(3, int64_t{height})
        .Bind(4, yaml)
        .Run();
  });
}

std::optional<std::string> MapDatabase::ReadCameraYaml() {
  SqliteStatement& s = database_->Prepare("SELECT yaml FROM cameras ORDER BY camera_id LIMIT 1;");
  std::optional<std::string> yaml;
  if (s.Step()) yaml = s.ColumnText(0);
  s.Reset();
  return yaml;
}

void MapDatabase::WriteNode(const MapNode& node) {
  const std::vector<uint8_t> image =
      node.image.empty() ? std::vector<uint8_t>() : EncodeImage(node.image, options_, path_.string());
  InTransaction([&] {
    SqliteStatement& insert_node = database_->Prepare(
        "INSERT INTO nodes (node_id, source_frame, image_name, timestamp, width, height, image) "
        "VALUES (?, ?, ?, ?, ?, ?, ?);");
    insert_node.Bind(1, int64_t{node.id})
        .Bind(2, int64_t{node.source_frame})
        .Bind(3, node.image_name)
        .Bind(4, node.timestamp)
        .Bind(5, int64_t{node.image.cols})
        .Bind(6, int64_t{node.image.rows});
    if (image.empty()) {
      insert_node.BindNull(7);
    } else {
      insert_node.BindBlob(7, image.data(), image.size());
    }
    insert_node.Run();
    WriteObservations(node.id, node.features);
  });
}

void MapDatabase::WriteObservations(node_t node, const std::vector<FeatureObservation>& features) {
  InTransaction([&] {
    SqliteStatement& insert_observation = database_->Prepare(
        "INSERT INTO observations (node_id, feature_id, x, y, patch_size, patch) VALUES (?, ?, ?, ?, ?, ?);");
    for (const FeatureObservation& f : features) {
      insert_observation.Bind(1, int64_t{node})
          .Bind(2, int64_t{f.feature_id})
          .Bind(3, f.position.x())
          .Bind(4, f.position.y())
          .Bind(5, int64_t{f.patch.rows});
      if (f.patch.empty()) {
        insert_observation.BindNull(6);
      } else {
        CV_Assert(f.patch.type() == CV_8UC1 && f.patch.rows == f.patch.cols);
        const cv::Mat patch = f.patch.isContinuous() ? f.patch : f.patch.clone();
        insert_observation.BindBlob(6, patch.data, patch.total());
      }
      insert_observation.Run();
    }
  });
}

void MapDatabase::WriteArc(const MapArc& arc) {
  InTransaction([&] {
    const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> rotation = arc.to_from_from.rotation;
    const Vector3d& t = arc.to_from_from.translation;
    database_->Prepare(
                 "INSERT INTO arcs (arc_id, from_node, to_node, kind, rotation, translation, sigma_p, num_features) "
                 "VALUES (?, ?, ?, ?, ?, ?, ?, ?);")
        .Bind(1, int64_t{arc.id})
        .Bind(2, int64_t{arc.from})
        .Bind(3, int64_t{arc.to})
        .Bind(4, arc.kind)
        .BindBlob(5, rotation.data(), 9 * sizeof(double))
        .BindBlob(6, t.data(), 3 * sizeof(double))
        .Bind(7, arc.sigma_p)
        .Bind(8, static_cast<int64_t>(arc.points.size()))
        .Run();
    SqliteStatement& insert_point =
        database_->Prepare("INSERT INTO arc_points (arc_id, feature_id, x, y, z) VALUES (?, ?, ?, ?, ?);");
    for (const ArcPoint& p : arc.points) {
      insert_point.Bind(1, int64_t{arc.id})
          .Bind(2, int64_t{p.feature_id})
          .Bind(3, p.point_in_from.x())
          .Bind(4, p.point_in_from.y())
          .Bind(5, p.point_in_from.z())
          .Run();
    }
  });
}

void MapDatabase::WriteScale(const NodeScale& scale) {
  InTransaction([&] {
    database_->Prepare("INSERT OR REPLACE INTO node_scales (node_id, arc_in, arc_out, scale) VALUES (?, ?, ?, ?);")
        .Bind(1, int64_t{scale.node})
        .Bind(2, int64_t{scale.arc_in})
        .Bind(3, int64_t{scale.arc_out})
        .Bind(4, scale.scale)
        .Run();
  });
}

Map MapDatabase::ReadMap(bool load_images) {
  const std::string source = path_.string();
  Map map;
  SqliteStatement& nodes = database_->Prepare(
      "SELECT node_id, source_frame, image_name, timestamp, width, height, image FROM nodes ORDER BY node_id;");
  while (nodes.Step()) {
    MapNode node;
    node.id = nodes.ColumnInt(0);
    node.source_frame = nodes.ColumnInt(1);
    node.image_name = nodes.ColumnText(2);
    node.timestamp = nodes.ColumnDouble(3);
    if (load_images && !nodes.ColumnIsNull(6)) {
      const std::vector<uint8_t> bytes = nodes.ColumnBlob(6);
      node.image = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
      if (node.image.empty() || node.image.cols != nodes.ColumnInt(4) || node.image.rows != nodes.ColumnInt(5)) {
        nodes.Reset();
        throw InputError(source, "corrupt key-image of node " + std::to_string(node.id));
      }
    }
    map.AddNode(std::move(node));
  }
  nodes.Reset();

  SqliteStatement& observations =
      database_->Prepare("SELECT node_id, feature_id, x, y, patch_size, patch FROM observations ORDER BY node_id;");
  while (observations.Step()) {
    FeatureObservation f;
    const node_t node_id = observations.ColumnInt(0);
    f.feature_id = observations.ColumnInt(1);
    f.position = Vector2d(observations.ColumnDouble(2), observations.ColumnDouble(3));
    const int size = static_cast<int>(observations.ColumnInt(4));
    if (!observations.ColumnIsNull(5)) {
      const std::vector<uint8_t> bytes = observations.ColumnBlob(5);
      if (size <= 0 || bytes.size() != static_cast<size_t>(size) * size) {
        observations.Reset();
        throw InputError(source, "corrupt reference patch of feature " + std::to_string(f.feature_id));
      }
      f.patch = cv::Mat(size, size, CV_8UC1);
      std::copy(bytes.begin(), bytes.end(), f.patch.data);
    }
    MapNode* node = map.MutableNode(node_id);
    if (node == nullptr) {
      observations.Reset();
      throw InputError(source, "observation refers to missing node " + std::to_string(node_id));
    }
    node->features.push_back(std::move(f));
  }
  observations.Reset();

  SqliteStatement& arcs = database_->Prepare(
      "SELECT arc_id, from_node, to_node, kind, rotation, translation, sigma_p FROM arcs ORDER BY arc_id;");
  while (arcs.Step()) {
    MapArc arc;
    arc.id = arcs.ColumnInt(0);
    arc.from = arcs.ColumnInt(1);
    arc.to = arcs.ColumnInt(2);
    arc.kind = arcs.ColumnText(3);
    const std::vector<uint8_t> rotation = arcs.ColumnBlob(4);
    const std::vector<uint8_t> translation = arcs.ColumnBlob(5);
    if (rotation.size() != 9 * sizeof(double) || translation.size() != 3 * sizeof(double)) {
      arcs.Reset();
      throw InputError(source, "corrupt geometry of arc " + std::to_string(arc.id));
    }
    arc.to_from_from.rotation =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(reinterpret_cast<const double*>(rotation.data()));
    arc.to_from_from.translation = Eigen::Map<const Vector3d>(reinterpret_cast<const double*>(translation.data()));
    arc.sigma_p = arcs.ColumnDouble(6);
    map.AddArc(std::move(arc));
  }
  arcs.Reset();

  SqliteStatement& points = database_->Prepare("SELECT arc_id, feature_id, x, y, z FROM arc_points ORDER BY arc_id;");
  while (points.Step()) {
    const arc_t arc_id = points.ColumnInt(0);
    MapArc* arc = map.MutableArc(arc_id);
    if (arc == nullptr) {
      points.Reset();
      throw InputError(source, "3D point refers to missing arc " + std::to_string(arc_id));
    }
    arc->points.push_back(
        {points.ColumnInt(1), Vector3d(points.ColumnDouble(2), points.ColumnDouble(3), points.ColumnDouble(4))});
  }
  points.Reset();

  SqliteStatement& scales = database_->Prepare("SELECT node_id, arc_in, arc_out, scale FROM node_scales;");
  while (scales.Step()) {
    map.AddScale({scales.ColumnInt(0), scales.ColumnInt(1), scales.ColumnInt(2), scales.ColumnDouble(3)});
  }
  scales.Reset();
  return map;
}

int64_t MapDatabase::ImageBytes() {
  SqliteStatement& s = database_->Prepare("SELECT COALESCE(SUM(LENGTH(image)), 0) FROM nodes;");
  s.Step();
  const int64_t bytes = s.ColumnInt(0);
  s.Reset();
  return bytes;
}

int64_t MapDatabase::NumNodes() {
  SqliteStatement& s = database_->Prepare("SELECT COUNT(*) FROM nodes;");
  s.Step();
  const int64_t n = s.ColumnInt(0);
  s.Reset();
  return n;
}

int64_t MapDatabase::NumArcs() {
  SqliteStatement& s = database_->Prepare("SELECT COUNT(*) FROM arcs;");
  s.Step();
  const int64_t n = s.ColumnInt(0);
  s.Reset();
  return n;
}

void MapDatabase::Checkpoint() { database_->Execute("PRAGMA wal_checkpoint(PASSIVE);"); }

}  // namespace retrace
