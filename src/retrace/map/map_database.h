#pragma once

// The map store: one SQLite database file per map (design §1; the layout follows COLMAP's database).
//
// Tables (plural snake_case, `*_id INTEGER PRIMARY KEY`, foreign keys with ON DELETE CASCADE):
//   metadata     key/value text: creation options, source sequence, retrace version, teach_state, ...
//   cameras      the camera model of the key-images, as retrace camera YAML
//   nodes        key-images with the image itself, compressed, so that a map is self-contained, the CRC-32 of
//                the compressed bytes (schema 2; maps of schema 1 have no checksum and are still read) and the
//                route (drive) that taught it (schema 3; 0 in older maps). width x height is the key-image's size;
//                the compressed image may be smaller by a whole factor (schema 5, MapDatabaseOptions::
//                max_image_downscale)
//   observations features seen in a node: position and reference patch (8-bit gray, row-major)
//   arcs         two-view geometry W_k between two nodes: R (9 doubles, row-major), t (3 doubles), σ_p, |M_k|,
//                kind, and the appearance similarity S_ij (schema 3, Booij 2007 §B.2; NULL = unknown, older maps)
//   arc_points   3D points Q_kj of an arc's features, in the `from` node's camera frame, arc units
//   node_scales  relative scale between the geometries of two arcs meeting at a node
//   signatures   what relocalization needs of a key-image (map.h KeyImageSignature): binary key-points and their
//                descriptors, the quantised appearance thumbnail, and a CRC-32 of the three (schema 4; maps of
//                schemas 1 to 3 have none: repeat computes them when it loads such a map). Metadata
//                `signature_features` / `signature_appearance` name the settings that made them.
// The schema version is in `PRAGMA user_version` and the file is marked as a retrace map by
// `PRAGMA application_id`, so opening a foreign file or a map of a newer schema gives a clear error.
//
// Opening a map checks it (CheckIntegrity(), the same for every command): SQLite's `PRAGMA integrity_check`, the tables
// and columns of the schema, every reference between tables (arcs to nodes, observations to nodes, points to arcs,
// scales to the two arcs they join at their node, and `PRAGMA foreign_key_check`) and the checksum of every
// key-image; ReadMap() then checks the values it reads (finite numbers, rotations, unit translations, image sizes).
// A map that fails is refused with one line naming the file and the first fault, in printable text only.
//
// Writes are transactional and the database runs in WAL mode: a process killed during teach leaves a map that
// opens and holds every key-image committed before. Close() (or the destructor) checkpoints the log into the single
// map file. Teach writes through StagedMap (below): the map is built in `<map>.incomplete`, marked incomplete, and
// moved onto `<map>` only when teach succeeded; one writer per map path at a time.

#include <filesystem>
#include <functional>
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
  // Quality of lossy codecs, 1-100: the highest used.
  int image_quality = 90;
  // Lossy codecs: each key-image is stored at the lowest quality (at least 20, at most image_quality) whose error,
  // as the tracker sees the image, is at most this many grey levels RMS; 0: always image_quality. The tracker aligns
  // its references on images smoothed by a Gaussian (TeachOptions::smoothing_sigma_px, `error_smoothing_px` pixels
  // per `error_reference_width` pixels of image width), which removes most of what a codec loses on large images.
  // 0.6: what JPEG at quality 90 costs a 320x240 image of the simulated town, where the validation matrix's figures
  // were measured (0.63 grey levels RMS after smoothing); kitti07 at 1226x370 stays within it near quality 50 (0.54).
  double max_image_error = 0.6;
  double error_smoothing_px = 0.7;
  int error_reference_width = 320;
  // Lossy codecs with max_image_error: a key-image may also be stored at 1/2, 1/3, ... 1/max_image_downscale of
  // its resolution (averaged over blocks, restored by bicubic interpolation when read), the smallest encoding within
  // the same error budget chosen. The larger the tracker's smoothing, the less a coarser resolution loses: on kitti07
  // at 1226x370 (2.7 px) half resolution alone costs 0.36-0.52 grey levels RMS (two frames, a throwaway program),
  // so that 14 of its 16 key-images are stored at half resolution near quality 85 (593 -> 410 kB), while a 320x240
  // image (0.7 px) keeps its resolution. 1: always full resolution (maps of schema < 5 are always written so).
  int max_image_downscale = 4;

  bool Check(std::string* error = nullptr) const;
};

class MapDatabase {
 public:
  // Written by this retrace. 2: key-image checksums; 3: arcs.similarity and nodes.route (graphs of several drives);
  // 4: key-image relocalization signatures; 5: key-images stored at a reduced resolution (MapDatabaseOptions::
  // max_image_downscale); 6: a key-image's features and an arc's 3D points as one blob each (tables node_features
  // and arc_point_lists, feature_blobs.h) instead of a row per feature and per point (tables observations and
  // arc_points, still read: a map upgraded for `teach --append` keeps its old rows); 7: relocalization descriptors
  // stored as their differences from the stored key-image's (signatures.descriptor_coding, descriptor_coding.h).
  static constexpr int kSchemaVersion = 7;
  static constexpr int kOldestSchemaVersion = 1;     // oldest schema still read
  static constexpr int kApplicationId = 0x52545243;  // "RTRC"
  // Metadata key of teach's progress: kIncomplete from the start of teach, kComplete when it finished. Maps
  // written before it was recorded have no such key and count as complete.
  static constexpr const char* kTeachStateKey = "teach_state";
  static constexpr const char* kIncomplete = "incomplete";
  static constexpr const char* kComplete = "complete";

  // Creates a new, empty map file. An existing file is replaced only when `overwrite` is true, and only when it is
  // a retrace map or empty (CheckReplaceable()).
  static std::unique_ptr<MapDatabase> Create(const std::filesystem::path& path,
                                             const MapDatabaseOptions& options = {}, bool overwrite = false);
  // Opens an existing map and checks its integrity (see the comment at the top). Throws InputError for a missing
  // file, a file that is not a retrace map, a map written by a newer retrace, or a map that fails the check.
  // Logs a warning when the map is incomplete (its teach was interrupted).
  static std::unique_ptr<MapDatabase> Open(const std::filesystem::path& path, bool writable = false);
  // Throws InputError unless `path` may be replaced by a new map: a regular file that is empty or whose header
  // marks it as a retrace map (the contents are not checked: a damaged map may be replaced).
  static void CheckReplaceable(const std::filesystem::path& path);

  ~MapDatabase();

  // Brings a map of an older schema, opened writable, to kSchemaVersion in one transaction: the columns added since
  // (similarity unknown, route 0) and the checksums of its key-images. Used before a drive is appended to it.
  void UpgradeSchema();
  int schema_version() const { return schema_version_; }

  // Whether teach finished this map (metadata kTeachStateKey).
  bool complete();

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
  // Stores a node's relocalization signature (also done by WriteNode when the node has one). Schema >= 3 only.
  // With a descriptor prediction set (schema >= 7) and the node's key-image stored before, the descriptors are
  // stored as their differences from the prediction on the key-image as it is read back (descriptor_coding.h).
  void WriteSignature(node_t node, const KeyImageSignature& signature);
  // The descriptors of `keypoints` (as stored: positions and sizes rounded to 1/8 px) computed on a decoded key-image,
  // one row per key-point; teach's is DescribeBinaryKeyPoints with its signature settings. Readers resolve the
  // stored differences (KeyImageSignature::descriptor_residual) with the same function.
  using DescriptorPrediction =
      std::function<cv::Mat(const cv::Mat& key_image, const std::vector<cv::KeyPoint>& keypoints)>;
  void SetDescriptorPrediction(DescriptorPrediction prediction) { descriptor_prediction_ = std::move(prediction); }
  void WriteArc(const MapArc& arc);
  void WriteScale(const NodeScale& scale);
  std::unique_ptr<SqliteTransaction> BeginTransaction();

  // Reads the whole map. Key-images are decoded only when `load_images` is true; the key-points and descriptors of
  // the relocalization signatures are kept only when `load_signature_features` is true (their appearance always).
  Map ReadMap(bool load_images = true, bool load_signature_features = true);
  // The relocalization signature of node `id` as ReadMap reads it (empty when the node has none). Throws InputError
  // naming the map when it is damaged.
  KeyImageSignature ReadSignature(node_t id);
  // Decodes the key-image of node `id` (8-bit gray), as ReadMap does. Throws InputError naming the map when the node
  // has none or it cannot be decoded to its stored size.
  cv::Mat ReadKeyImage(node_t id);
  // Encoded size of every stored key-image, in bytes.
  int64_t ImageBytes();
  // Stored size of the key-images' relocalization signatures, in bytes (0 for maps of schema < 4).
  int64_t SignatureBytes();
  int64_t NumNodes();
  int64_t NumArcs();

  // Checkpoints the write-ahead log into the map file; further writes are still possible.
  void Checkpoint();
  // Folds the write-ahead log into the map file, leaves rollback-journal mode (no side files) and closes the file.
  // Throws InputError when that fails. Nothing else may be called afterwards.
  void Close();
  // The integrity check Open() runs (see the comment at the top); throws InputError at the first fault.
  void CheckIntegrity();

  const std::filesystem::path& path() const { return path_; }

 private:
  friend class StagedMap;  // sets the journal mode of a map it appends to
  MapDatabase(const std::filesystem::path& path, SqliteDatabase::Mode mode, const MapDatabaseOptions& options);
  void CreateTables();
  void CheckIsRetraceMap();
  void CheckSchema();
  void CheckReferences();
  void CheckKeyImages();
  template <typename Writer>
  void InTransaction(Writer&& writer);

  std::filesystem::path path_;
  MapDatabaseOptions options_;
  std::unique_ptr<SqliteDatabase> database_;
  bool writable_;
  int schema_version_ = kSchemaVersion;
  DescriptorPrediction descriptor_prediction_;
};

// A map written beside its destination and moved into place only when complete; what retrace teach writes with.
//  - `<path>.lock` is locked (flock) while the map is written, so a second writer of the same path fails at once
//    with a one-line error; the lock file is removed when the writer is done (a killed writer leaves it, unlocked).
//  - The map is written to `<path>.incomplete` (a stale one from an interrupted teach is replaced), with metadata
//    teach_state = incomplete, in WAL mode: a writer killed at any point leaves there a map that opens, holds every
//    key-image committed before and says it is incomplete; `<path>` is untouched.
//  - Commit() marks it complete, folds the log into the one file and renames it onto `<path>` atomically (only
//    then is an old map replaced, and only with `overwrite`). Stale -wal/-shm/-journal files of `<path>` are
//    removed first, so they can never be applied to the new map.
//  - Destroyed without Commit() (an error during teach): `<path>.incomplete` stays, marked incomplete, for
//    inspection; `<path>` is untouched.
class StagedMap {
 public:
  // Checks that `path` may be written (absent; or, with `overwrite`, a retrace map or an empty file), takes the
  // lock and creates the staging map. Throws InputError naming `path` otherwise.
  static std::unique_ptr<StagedMap> Begin(const std::filesystem::path& path, const MapDatabaseOptions& options = {},
                                          bool overwrite = false);
  // The same for adding to the existing map at `path` (`teach --append`): the map is checked (MapDatabase::Open),
  // copied to `<path>.incomplete`, upgraded to the current schema there (MapDatabase::UpgradeSchema) and marked
  // incomplete; Commit() moves it back onto `<path>`. A failed append leaves `<path>` byte-identical.
  static std::unique_ptr<StagedMap> BeginAppend(const std::filesystem::path& path);
  ~StagedMap();
  StagedMap(const StagedMap&) = delete;
  StagedMap& operator=(const StagedMap&) = delete;

  // The map being written; null after Commit().
  MapDatabase* database() { return database_.get(); }
  // Marks the map complete and moves it onto path(); throws InputError (leaving path() untouched) when it cannot.
  void Commit();

  const std::filesystem::path& path() const { return path_; }
  const std::filesystem::path& staging_path() const { return staging_path_; }
  static std::filesystem::path StagingPathFor(const std::filesystem::path& path);
  static std::filesystem::path LockPathFor(const std::filesystem::path& path);

 private:
  StagedMap(const std::filesystem::path& path, bool overwrite);
  // Takes `<path>.lock` (see Begin).
  void Lock();

  std::filesystem::path path_;
  std::filesystem::path staging_path_;
  std::filesystem::path lock_path_;
  bool overwrite_ = false;
  int lock_fd_ = -1;
  std::unique_ptr<MapDatabase> database_;
};

}  // namespace retrace
