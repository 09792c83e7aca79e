#pragma once

// The map store: one SQLite database file per map (design §1; the layout follows COLMAP's database).
//
// Tables (plural snake_case, `*_id INTEGER PRIMARY KEY`, foreign keys with ON DELETE CASCADE):
//   metadata     key/value text: creation options, source sequence, retrace version, ...
//   cameras      the camera model of the key-images, as retrace camera YAML
//   nodes        key-images with the image itself, compressed, so that a map is self-contained
//   observations features seen in a node: position and reference patch (8-bit gray, row-major)
//   arcs         two-view geometry W_k between two nodes: R (9 doubles, row-major), t (3 doubles), σ_p, |M_k|
//   arc_points   3D points Q_kj of an arc's features, in the `from` node's camera frame, arc units
//   node_scales  relative scale between the geometries of two arcs meeting at a node
// The schema version is in `PRAGMA user_version` and the file is marked as a retrace map by
// `PRAGMA application_id`, so opening a foreign file or a map of a newer schema gives a clear error.
//
// Writes are transactional and the database runs in WAL mode: a process killed during teach leaves a map that
// opens and holds every key-image committed before. Close() (or the destructor) checkpoints the log into the single
// map file.

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "retrace/map/map.h"
#include "retrace/map/sqlite.h"

namespace retrace {

struct MapDatabaseOptions {
  // Codec of the stored key-images, as an OpenCV file extension: ".png" (lossless), ".jpg" or ".webp".
  std::string image_format = ".jpg";
  // Quality of lossy codecs, 1-100.
  int image_quality = 90;

  bool Check(std::string* error = nullptr) const;
};

class MapDatabase {
 public:
  static constexpr int kSchemaVersion = 1;
  static constexpr int kApplicationId = 0x52545243;  // "RTRC"

  // Creates a new, empty map file. An existing file is replaced only when `overwrite` is true.
  static std::unique_ptr<MapDatabase> Create(const std::filesystem::path& path,
                                             const MapDatabaseOptions& options = {}, bool overwrite = false);
  // Opens an existing map. Throws InputError for a missing file, a file that is not a retrace map, or a map
  // written by a newer retrace.
  static std::unique_ptr<MapDatabase> Open(const std::filesystem::path& path, bool writable = false);

  ~MapDatabase();

  void SetMetadata(const std::string& key, const std::string& value);
  std::optional<std::string> Metadata(const std::string& key);
  std::map<std::string, std::string> AllMetadata();

  // Camera of the key-images: model name, image size and the camera's YAML text (see camera/camera_io.h).
  void WriteCamera(const std::string& model, int width, int height, const std::string& yaml);
  std::optional<std::string> ReadCameraYaml();

  // Each write runs in its own transaction unless the caller holds one (BeginTransaction()), which is how teach
  // commits a key-image together with the arc that reaches it.
  void WriteNode(const MapNode& node);
  // Adds observations to a node written before (e.g. features found later by wide-baseline matching).
  void WriteObservations(node_t node, const std::vector<FeatureObservation>& features);
  void WriteArc(const MapArc& arc);
  void WriteScale(const NodeScale& scale);
  std::unique_ptr<SqliteTransaction> BeginTransaction();

  // Reads the whole map. Key-images are decoded only when `load_images` is true.
  Map ReadMap(bool load_images = true);
  // Encoded size of every stored key-image, in bytes.
  int64_t ImageBytes();
  int64_t NumNodes();
  int64_t NumArcs();

  // Checkpoints the write-ahead log into the map file; further writes are still possible.
  void Checkpoint();

  const std::filesystem::path& path() const { return path_; }

 private:
  MapDatabase(const std::filesystem::path& path, SqliteDatabase::Mode mode, const MapDatabaseOptions& options);
  void CreateTables();
  void CheckIsRetraceMap();
  template <typename Writer>
  void InTransaction(Writer&& writer);

  std::filesystem::path path_;
  MapDatabaseOptions options_;
  std::unique_ptr<SqliteDatabase> database_;
  bool writable_;
};

}  // namespace retrace
