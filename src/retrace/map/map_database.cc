#include "retrace/map/map_database.h"

#include <fcntl.h>
#include <stdio.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <unordered_set>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "retrace/map/descriptor_coding.h"
#include "retrace/map/feature_blobs.h"
#include "retrace/util/error.h"
#include "retrace/util/version.h"

namespace retrace {
namespace {

constexpr const char* kCorrupt = "corrupt map: ";

// CRC-32 (IEEE 802.3, as zlib's crc32) of `size` bytes.
uint32_t Crc32(const uint8_t* data, size_t size) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int bit = 0; bit < 8; ++bit) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xFF] ^ (crc >> 8);
  return crc ^ 0xFFFFFFFFu;
}

// Whether `bytes` look like a whole encoded image of a codec a map may hold (maps of schema 1 have no checksum:
// this at least finds a truncated or overwritten start or end).
bool LooksLikeWholeImage(const std::vector<uint8_t>& bytes) {
  const auto starts_with = [&](std::initializer_list<uint8_t> prefix) {
    return bytes.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), bytes.begin());
  };
  if (starts_with({0xFF, 0xD8, 0xFF})) {
    return bytes.size() >= 4 && bytes[bytes.size() - 2] == 0xFF && bytes.back() == 0xD9;
  }
  if (starts_with({0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'})) {
    static const uint8_t kEnd[] = {'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
    return bytes.size() >= 8 + sizeof(kEnd) && std::equal(std::begin(kEnd), std::end(kEnd), bytes.end() - sizeof(kEnd));
  }
  if (starts_with({'R', 'I', 'F', 'F'}) && bytes.size() >= 12) {
    const uint32_t riff_size = bytes[4] | (bytes[5] << 8) | (bytes[6] << 16) | (uint32_t{bytes[7]} << 24);
    return std::equal(bytes.begin() + 8, bytes.begin() + 12, "WEBP") && riff_size + 8 == bytes.size();
  }
  return false;
}

// Runs `sql` (an insert of an id, a blob and its checksum) on `bytes` (schema 6's tables of features and points).
void InsertChecksummedBlob(SqliteDatabase* database, const char* sql, int64_t id, const std::vector<uint8_t>& bytes) {
  static const uint8_t kNothing = 0;  // a null pointer would bind SQL NULL; no features stores an empty blob
  database->Prepare(sql)
      .Bind(1, id)
      .BindBlob(2, bytes.empty() ? &kNothing : bytes.data(), bytes.size())
      .Bind(3, int64_t{Crc32(bytes.data(), bytes.size())})
      .Run();
}

// The side files SQLite may keep beside a database.
std::vector<std::filesystem::path> SideFiles(const std::filesystem::path& path) {
  return {path.string() + "-wal", path.string() + "-shm", path.string() + "-journal"};
}

void RemoveSideFiles(const std::filesystem::path& path) {
  std::error_code ec;
  for (const auto& side : SideFiles(path)) {
    std::filesystem::remove(side, ec);
    if (ec) throw InputError(path.string(), "cannot remove " + side.string() + ": " + ec.message());
  }
}

// fsync of a file or directory; errors are ignored (durability is best effort, atomicity is the rename's).
void SyncPath(const std::filesystem::path& path, bool directory) {
  const int fd = open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) return;
  fsync(fd);
  close(fd);
}

// Key-images may be stored at 1/2 to 1/kMaxImageDownscale of their resolution (schema 5), never with a side below
// kMinStoredImageSide pixels.
constexpr int kMaxImageDownscale = 8;
constexpr int kMinStoredImageSide = 32;

// A key-image stored at 1/`downscale` of its resolution: the image, extended to a multiple of `downscale` on each
// side by repeating its last row and column, averaged over `downscale` x `downscale` blocks, so that the stored
// pixel (u, v) covers exactly the original pixels downscale * (u, v) + [0, downscale)^2.
cv::Size ReducedSize(int64_t width, int64_t height, int downscale) {
  return {static_cast<int>((width + downscale - 1) / downscale),
          static_cast<int>((height + downscale - 1) / downscale)};
}

cv::Mat ReduceKeyImage(const cv::Mat& image, int downscale) {
  const cv::Size size = ReducedSize(image.cols, image.rows, downscale);
  cv::Mat extended;
  cv::copyMakeBorder(image, extended, 0, size.height * downscale - image.rows, 0, size.width * downscale - image.cols,
                     cv::BORDER_REPLICATE);
  cv::Mat reduced;
  cv::resize(extended, reduced, size, 0, 0, cv::INTER_AREA);
  return reduced;
}

// The inverse of ReduceKeyImage up to what it lost: bicubic interpolation by the same whole factor (the pixel
// centres keep their places), cut to width x height.
cv::Mat RestoreKeyImage(const cv::Mat& reduced, int64_t width, int64_t height, int downscale) {
  cv::Mat restored;
  cv::resize(reduced, restored, cv::Size(reduced.cols * downscale, reduced.rows * downscale), 0, 0, cv::INTER_CUBIC);
  return restored(cv::Rect(0, 0, static_cast<int>(width), static_cast<int>(height))).clone();
}

// A key-image from its stored bytes (8-bit gray), or the reason it is damaged; `name` says which. A key-image stored
// at a reduced resolution (ReduceKeyImage, 1/2 to 1/kMaxImageDownscale) is brought back to width x height.
std::optional<std::string> DecodeKeyImage(const std::vector<uint8_t>& bytes, int64_t width, int64_t height,
                                          const std::string& name, cv::Mat* image) {
  *image = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
  if (image->empty()) return name + " cannot be decoded";
  if (image->cols == width && image->rows == height) return std::nullopt;
  for (int downscale = 2; downscale <= kMaxImageDownscale; ++downscale) {
    if (image->size() == ReducedSize(width, height, downscale)) {
      *image = RestoreKeyImage(*image, width, height, downscale);
      return std::nullopt;
    }
  }
  return fmt::format("{} is {}x{} but is stored as {}x{}", name, image->cols, image->rows, width, height);
}

// The key-image's stored bytes: at `options.image_quality`, or, for lossy codecs, the smallest encoding (quality
// and resolution) whose error as the tracker sees it stays within `options.max_image_error` (map_database.h).
// Reduced resolutions are tried only when `allow_reduced` (maps of schema >= 5).
std::vector<uint8_t> EncodeImage(const cv::Mat& image, const MapDatabaseOptions& options, bool allow_reduced,
                                 const std::string& source) {
  const bool lossy = options.image_format == ".jpg" || options.image_format == ".webp";
  const auto encode = [&](const cv::Mat& stored, int quality) {
    std::vector<int> params;
    if (options.image_format == ".jpg") params = {cv::IMWRITE_JPEG_QUALITY, quality};
    if (options.image_format == ".webp") params = {cv::IMWRITE_WEBP_QUALITY, quality};
    std::vector<uint8_t> bytes;
    if (!cv::imencode(options.image_format, stored, bytes, params)) {
      throw InputError(source, "cannot encode key-image as " + options.image_format);
    }
    return bytes;
  };
  std::vector<uint8_t> best = encode(image, options.image_quality);
  if (!lossy || !(options.max_image_error > 0) || image.type() != CV_8UC1) return best;
  // The error as the tracker sees it: RMS grey levels between the smoothed image and its smoothed decoding (brought
  // back to full resolution as DecodeKeyImage does).
  const double sigma = options.error_smoothing_px * image.cols / options.error_reference_width;
  const auto smoothed = [sigma](const cv::Mat& gray) {
    cv::Mat out;
    gray.convertTo(out, CV_32F);
    if (sigma > 0) cv::GaussianBlur(out, out, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
    return out;
  };
  const cv::Mat original = smoothed(image);
  const auto within_budget = [&](const std::vector<uint8_t>& bytes) {
    cv::Mat decoded;
    if (DecodeKeyImage(bytes, image.cols, image.rows, "", &decoded)) return false;
    const double rms = cv::norm(smoothed(decoded), original, cv::NORM_L2) / std::sqrt(static_cast<double>(image.total()));
    return rms <= options.max_image_error;
  };
  const int max_downscale = allow_reduced ? options.max_image_downscale : 1;
  for (int downscale = 1; downscale <= max_downscale; ++downscale) {
    const cv::Size size = ReducedSize(image.cols, image.rows, downscale);
    if (downscale > 1 && std::min(size.width, size.height) < kMinStoredImageSide) break;
    const cv::Mat stored = downscale > 1 ? ReduceKeyImage(image, downscale) : image;
    std::vector<uint8_t> highest = downscale > 1 ? encode(stored, options.image_quality) : best;
    // Over the budget at the highest quality: the full resolution at that quality (the default) or, at a coarser
    // resolution, nothing better, as the still coarser ones lose more.
    if (!within_budget(highest)) break;
    if (highest.size() < best.size()) best = std::move(highest);
    // Bisection on the quality (the error grows as the quality falls), to within 2 quality steps.
    constexpr int kLowestQuality = 20;
    int low = kLowestQuality - 1, high = options.image_quality;  // high is within the budget, low is not known to be
    while (high - low > 2) {
      const int middle = (low + high) / 2;
      std::vector<uint8_t> bytes = encode(stored, middle);
      if (within_budget(bytes)) {
        high = middle;
        if (bytes.size() < best.size()) best = std::move(bytes);
      } else {
        low = middle;
      }
    }
  }
  return best;
}

// A key-image's signature (map.h) as stored in table signatures: key-points as three little-endian uint16 each
// (x, y and size in 1/8 px), descriptors as 8-32 bytes each (the same for all; BinaryFeatureOptions::descriptor_bytes,
// 32 before it existed), the appearance thumbnail as its bytes.
constexpr int kKeypointBytes = 6;
constexpr size_t kMaxDescriptorBytes = 32;
constexpr double kKeypointUnit = 8.0;  // stored units per pixel
// signatures.descriptor_coding (schema 7): the descriptors themselves, or their differences from the stored
// key-image's (descriptor_coding.h).
constexpr int64_t kDescriptorsVerbatim = 0;
constexpr int64_t kDescriptorDifferences = 1;

// The key-points as DecodeSignature reads them back.
std::vector<cv::KeyPoint> StoredKeypoints(const std::vector<uint8_t>& bytes) {
  std::vector<cv::KeyPoint> keypoints(bytes.size() / kKeypointBytes);
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const uint8_t* k = bytes.data() + i * kKeypointBytes;
    const auto value = [k](int j) { return static_cast<float>((k[2 * j] | (k[2 * j + 1] << 8)) / kKeypointUnit); };
    keypoints[i] = cv::KeyPoint(value(0), value(1), value(2));
  }
  return keypoints;
}

// A signature from its stored columns (the key-points and descriptors only when `features`), or the reason it is
// damaged. Key-points must lie in the `image_width` x `image_height` key-image.
std::optional<std::string> DecodeSignature(const std::vector<uint8_t>& keypoints,
                                           const std::vector<uint8_t>& descriptors, int64_t width, int64_t height,
                                           const std::vector<uint8_t>& appearance, int64_t image_width,
                                           int64_t image_height, bool features, KeyImageSignature* s,
                                           int64_t coding = kDescriptorsVerbatim) {
  const bool differences = coding == kDescriptorDifferences;
  if (!differences && coding != kDescriptorsVerbatim) return fmt::format("has an unknown descriptor coding {}", coding);
  const size_t count = keypoints.size() / kKeypointBytes;
  const size_t descriptor_bytes = count > 0 && !differences ? descriptors.size() / count : 0;
  if (keypoints.size() % kKeypointBytes != 0 || count > (1u << 20) ||
      (!differences && (descriptors.size() != count * descriptor_bytes || descriptor_bytes % 8 != 0 ||
                        descriptor_bytes > kMaxDescriptorBytes || (count > 0 && descriptor_bytes == 0)))) {
    return "has key-points and descriptors of mismatched sizes";
  }
  if (differences) {
    if (auto fault = CheckDescriptorResidual(descriptors, count)) return fault;
  }
  if (width < 1 || height < 1 || width > 1024 || height > 1024 ||
      appearance.size() != static_cast<size_t>(width * height)) {
    return "has an appearance of the wrong size";
  }
  if (features) {
    s->keypoints = StoredKeypoints(keypoints);
    for (size_t i = 0; i < count; ++i) {
      if (s->keypoints[i].pt.x > image_width || s->keypoints[i].pt.y > image_height) {
        return fmt::format("has key-point {} outside the {}x{} key-image", i, image_width, image_height);
      }
    }
    if (differences) {
      s->descriptor_residual = descriptors;
    } else {
      s->descriptors = cv::Mat(static_cast<int>(count), static_cast<int>(descriptor_bytes), CV_8UC1);
      if (count > 0) std::copy(descriptors.begin(), descriptors.end(), s->descriptors.data);
    }
  }
  s->appearance = cv::Mat(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  std::copy(appearance.begin(), appearance.end(), s->appearance.data);
  return std::nullopt;
}

std::vector<uint8_t> EncodeKeypoints(const std::vector<cv::KeyPoint>& keypoints, const std::string& source) {
  std::vector<uint8_t> bytes;
  bytes.reserve(keypoints.size() * kKeypointBytes);
  for (const cv::KeyPoint& k : keypoints) {
    for (const float value : {k.pt.x, k.pt.y, k.size}) {
      const long units = std::lround(value * kKeypointUnit);
      if (!(value >= 0.0f) || units > 0xFFFF) {
        throw InputError(source, fmt::format("key-point coordinate {} cannot be stored (0..8191 px)", value));
      }
      bytes.push_back(static_cast<uint8_t>(units & 0xFF));
      bytes.push_back(static_cast<uint8_t>(units >> 8));
    }
  }
  return bytes;
}

uint32_t SignatureCrc32(const std::vector<uint8_t>& keypoints, const std::vector<uint8_t>& descriptors,
                        const std::vector<uint8_t>& appearance) {
  std::vector<uint8_t> all(keypoints);
  all.insert(all.end(), descriptors.begin(), descriptors.end());
  all.insert(all.end(), appearance.begin(), appearance.end());
  return Crc32(all.data(), all.size());
}

std::vector<uint8_t> MatBytes(const cv::Mat& mat) {
  const cv::Mat continuous = mat.isContinuous() ? mat : mat.clone();
  return std::vector<uint8_t>(continuous.data, continuous.data + continuous.total() * continuous.elemSize());
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
  if (!(max_image_error >= 0) || !std::isfinite(max_image_error)) return fail("max_image_error must be >= 0");
  if (max_image_downscale < 1 || max_image_downscale > kMaxImageDownscale) {
    return fail("max_image_downscale must be in 1.." + std::to_string(kMaxImageDownscale));
  }
  if (!(error_smoothing_px >= 0) || !std::isfinite(error_smoothing_px) || error_reference_width <= 0) {
    return fail("error_smoothing_px must be >= 0 and error_reference_width > 0");
  }
  return true;
}

void MapDatabase::CheckReplaceable(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec) throw InputError(source, "cannot be examined: " + ec.message());
  if (!std::filesystem::is_regular_file(status)) {
    throw InputError(source, "not a regular file; refusing to overwrite it with a map");
  }
  if (std::filesystem::file_size(path, ec) == 0 && !ec) return;
  std::array<uint8_t, 100> header{};
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(header.data()), header.size());
  const bool is_sqlite = in.gcount() == static_cast<std::streamsize>(header.size()) &&
                         std::memcmp(header.data(), "SQLite format 3", 16) == 0;
  // The header stores application_id big-endian at offset 68.
  const uint32_t application_id = (uint32_t{header[68]} << 24) | (header[69] << 16) | (header[70] << 8) | header[71];
  if (!is_sqlite || application_id != static_cast<uint32_t>(kApplicationId)) {
    throw InputError(source, "not a retrace map; refusing to overwrite it (remove it first)");
  }
}

MapDatabase::MapDatabase(const std::filesystem::path& path, SqliteDatabase::Mode mode,
                         const MapDatabaseOptions& options)
    : path_(path),
      options_(options),
      database_(std::make_unique<SqliteDatabase>(path, mode)),
      writable_(mode != SqliteDatabase::Mode::kReadOnly) {}

MapDatabase::~MapDatabase() {
  if (!writable_ || !database_) return;
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
    CheckReplaceable(path);
    std::filesystem::remove(path, ec);
    RemoveSideFiles(path);
    if (std::filesystem::exists(path)) throw InputError(path.string(), "cannot replace the existing file");
  } else {
    RemoveSideFiles(path);  // never let a stale log of another database be applied to the new one
  }
  std::unique_ptr<MapDatabase> map(new MapDatabase(path, SqliteDatabase::Mode::kCreate, options));
  // The marks first, still in rollback-journal mode, so that they are in the file itself from the start (in WAL
  // mode page 1 would live in the log until a checkpoint, and a killed writer's file would not look like a map).
  map->database_->Execute("PRAGMA application_id=" + std::to_string(kApplicationId) + ";");
  map->database_->Execute("PRAGMA user_version=" + std::to_string(kSchemaVersion) + ";");
  map->database_->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL; PRAGMA foreign_keys=ON;");
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
  map->CheckIntegrity();
  if (const auto format = map->Metadata("image_format")) map->options_.image_format = *format;
  if (!map->complete()) {
    spdlog::warn("{}: incomplete map: its teach did not finish; it holds the key-images taught until then",
                 PrintableText(path.string()));
  }
  return map;
}

bool MapDatabase::complete() { return Metadata(kTeachStateKey).value_or(kComplete) != kIncomplete; }

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
  if (version < kOldestSchemaVersion) throw InputError(source, "not a retrace map (no schema version)");
  schema_version_ = static_cast<int>(version);
}

void MapDatabase::CheckIntegrity() {
  const std::string source = path_.string();
  {
    // Pages, b-trees, records, NOT NULL, and that indexes match their tables (quick_check skips that, and a damaged
    // index made one command fail and another read on).
    SqliteStatement& check = database_->Prepare("PRAGMA integrity_check(1);");
    std::string result = check.Step() ? check.ColumnText(0) : "no result";
    check.Reset();
    if (result != "ok") {
      const std::string kDatabaseName = "*** in database main ***";  // SQLite's heading, no news in one line
      if (result.rfind(kDatabaseName, 0) == 0) result.erase(0, kDatabaseName.size());
      throw InputError(source, kCorrupt + PrintableText(result));
    }
  }
  CheckSchema();
  CheckReferences();
  CheckKeyImages();
}

void MapDatabase::CheckSchema() {
  const std::string source = path_.string();
  std::vector<std::pair<std::string, std::vector<std::string>>> tables = {
      {"metadata", {"key", "value"}},
      {"cameras", {"camera_id", "model", "width", "height", "yaml"}},
      {"nodes", {"node_id", "source_frame", "image_name", "timestamp", "width", "height", "image"}},
      {"observations", {"node_id", "feature_id", "x", "y", "patch_size", "patch"}},
      {"arcs", {"arc_id", "from_node", "to_node", "kind", "rotation", "translation", "sigma_p", "num_features"}},
      {"arc_points", {"arc_id", "feature_id", "x", "y", "z"}},
      {"node_scales", {"node_id", "arc_in", "arc_out", "scale"}}};
  if (schema_version_ >= 2) tables[2].second.push_back("image_crc32");
  if (schema_version_ >= 3) {
    tables[2].second.push_back("route");
    tables[4].second.push_back("similarity");
  }
  if (schema_version_ >= 4) {
    tables.push_back({"signatures", {"node_id", "keypoints", "descriptors", "appearance_width", "appearance_height",
                                     "appearance", "crc32"}});
  }
  if (schema_version_ >= 7) tables.back().second.push_back("descriptor_coding");
  if (schema_version_ >= 6) {
    tables.push_back({"node_features", {"node_id", "features", "crc32"}});
    tables.push_back({"arc_point_lists", {"arc_id", "points", "crc32"}});
  }
  SqliteStatement& columns = database_->Prepare("SELECT name FROM pragma_table_info(?);");
  for (const auto& [table, expected] : tables) {
    columns.Bind(1, table);
    std::vector<std::string> present;
    while (columns.Step()) present.push_back(columns.ColumnText(0));
    columns.Reset();
    if (present.empty()) throw InputError(source, kCorrupt + std::string("no table ") + table);
    for (const std::string& column : expected) {
      if (std::find(present.begin(), present.end(), column) == present.end()) {
        throw InputError(source, kCorrupt + fmt::format("table {} has no column {}", table, column));
      }
    }
  }
}

void MapDatabase::CheckReferences() {
  const std::string source = path_.string();
  // Each query returns the first offending row; the message names its ids.
  struct Reference {
    const char* sql;
    const char* message;  // fmt pattern over the row's integer columns
    int num_columns;
  };
  static const Reference kReferences[] = {
      {"SELECT arc_id, from_node FROM arcs WHERE from_node NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
       "arc {} starts at missing node {}", 2},
      {"SELECT arc_id, to_node FROM arcs WHERE to_node NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
       "arc {} ends at missing node {}", 2},
      {"SELECT arc_id, from_node FROM arcs WHERE from_node = to_node LIMIT 1;", "arc {} leads from node {} to itself",
       2},
      {"SELECT node_id FROM observations WHERE node_id NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
       "features of missing node {}", 1},
      {"SELECT arc_id FROM arc_points WHERE arc_id NOT IN (SELECT arc_id FROM arcs) LIMIT 1;",
       "3D points of missing arc {}", 1},
      {"SELECT node_id FROM node_scales WHERE node_id NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
       "scale at missing node {}", 1},
      {"SELECT node_id, arc_in FROM node_scales WHERE arc_in NOT IN (SELECT arc_id FROM arcs) LIMIT 1;",
       "scale at node {} refers to missing arc {}", 2},
      {"SELECT node_id, arc_out FROM node_scales WHERE arc_out NOT IN (SELECT arc_id FROM arcs) LIMIT 1;",
       "scale at node {} refers to missing arc {}", 2},
      {"SELECT s.node_id, s.arc_in, s.arc_out FROM node_scales s JOIN arcs i ON i.arc_id = s.arc_in "
       "JOIN arcs o ON o.arc_id = s.arc_out WHERE i.to_node != s.node_id OR o.from_node != s.node_id LIMIT 1;",
       "scale at node {} does not join arc {} to arc {} there", 3},
      {"SELECT n.node_id, n.width, n.height FROM nodes n, (SELECT width, height FROM cameras ORDER BY camera_id "
       "LIMIT 1) c WHERE n.image IS NOT NULL AND (n.width != c.width OR n.height != c.height) LIMIT 1;",
       "key-image of node {} is {}x{}, not the size of the map's camera", 3},
  };
  for (const Reference& reference : kReferences) {
    SqliteStatement& query = database_->Prepare(reference.sql);
    if (query.Step()) {
      std::vector<int64_t> ids;
      for (int i = 0; i < reference.num_columns; ++i) ids.push_back(query.ColumnInt(i));
      query.Reset();
      const auto pattern = fmt::runtime(reference.message);
      const std::string what = reference.num_columns == 1   ? fmt::format(pattern, ids[0])
                               : reference.num_columns == 2 ? fmt::format(pattern, ids[0], ids[1])
                                                            : fmt::format(pattern, ids[0], ids[1], ids[2]);
      throw InputError(source, kCorrupt + what);
    }
    query.Reset();
  }
  std::vector<std::pair<const char*, const char*>> newer;  // query, message of the tables of newer schemas
  if (schema_version_ >= 4) {
    newer.emplace_back("SELECT node_id FROM signatures WHERE node_id NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
                       "relocalization signature of missing node {}");
  }
  if (schema_version_ >= 6) {
    newer.emplace_back("SELECT node_id FROM node_features WHERE node_id NOT IN (SELECT node_id FROM nodes) LIMIT 1;",
                       "features of missing node {}");
    newer.emplace_back("SELECT arc_id FROM arc_point_lists WHERE arc_id NOT IN (SELECT arc_id FROM arcs) LIMIT 1;",
                       "3D points of missing arc {}");
  }
  for (const auto& [sql, message] : newer) {
    SqliteStatement& query = database_->Prepare(sql);
    if (query.Step()) {
      const int64_t id = query.ColumnInt(0);
      query.Reset();
      throw InputError(source, kCorrupt + fmt::format(fmt::runtime(message), id));
    }
    query.Reset();
  }
  // Whatever else the schema declares (a catch-all behind the named checks above).
  SqliteStatement& foreign_keys = database_->Prepare("PRAGMA foreign_key_check;");
  if (foreign_keys.Step()) {
    const std::string table = PrintableText(foreign_keys.ColumnText(0));
    const std::string parent = PrintableText(foreign_keys.ColumnText(2));
    foreign_keys.Reset();
    throw InputError(source, kCorrupt + fmt::format("a row of {} refers to a missing row of {}", table, parent));
  }
  foreign_keys.Reset();
}

void MapDatabase::CheckKeyImages() {
  const std::string source = path_.string();
  const bool has_checksums = schema_version_ >= 2;
  SqliteStatement& images = database_->Prepare(has_checksums ? "SELECT node_id, image, image_crc32 FROM nodes;"
                                                             : "SELECT node_id, image FROM nodes;");
  while (images.Step()) {
    if (images.ColumnIsNull(1)) continue;
    const int64_t node = images.ColumnInt(0);
    const std::vector<uint8_t> bytes = images.ColumnBlob(1);
    std::string fault;
    if (has_checksums) {
      if (images.ColumnIsNull(2)) {
        fault = "has no checksum";
      } else if (static_cast<uint32_t>(images.ColumnInt(2)) != Crc32(bytes.data(), bytes.size())) {
        fault = "is corrupt (checksum mismatch)";
      }
    } else if (!LooksLikeWholeImage(bytes)) {
      fault = "is corrupt (not a whole JPEG, PNG or WebP image)";
    }
    if (!fault.empty()) {
      images.Reset();
      throw InputError(source, kCorrupt + fmt::format("key-image of node {} {}", node, fault));
    }
  }
  images.Reset();
  if (schema_version_ < 4) return;
  SqliteStatement& signatures =
      database_->Prepare("SELECT node_id, keypoints, descriptors, appearance, crc32 FROM signatures;");
  while (signatures.Step()) {
    const int64_t node = signatures.ColumnInt(0);
    if (static_cast<uint32_t>(signatures.ColumnInt(4)) !=
        SignatureCrc32(signatures.ColumnBlob(1), signatures.ColumnBlob(2), signatures.ColumnBlob(3))) {
      signatures.Reset();
      throw InputError(source,
                       kCorrupt + fmt::format("relocalization signature of node {} is corrupt (checksum mismatch)", node));
    }
  }
  signatures.Reset();
  if (schema_version_ < 6) return;
  static const std::pair<const char*, const char*> kBlobTables[] = {
      {"SELECT node_id, features, crc32 FROM node_features;", "features of node"},
      {"SELECT arc_id, points, crc32 FROM arc_point_lists;", "3D points of arc"}};
  for (const auto& [sql, what] : kBlobTables) {
    SqliteStatement& blobs = database_->Prepare(sql);
    while (blobs.Step()) {
      const std::vector<uint8_t> bytes = blobs.ColumnBlob(1);
      if (static_cast<uint32_t>(blobs.ColumnInt(2)) != Crc32(bytes.data(), bytes.size())) {
        const int64_t id = blobs.ColumnInt(0);
        blobs.Reset();
        throw InputError(source, kCorrupt + fmt::format("{} {} are corrupt (checksum mismatch)", what, id));
      }
    }
    blobs.Reset();
  }
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
      image BLOB,
      image_crc32 INTEGER,
      route INTEGER NOT NULL DEFAULT 0);
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
      num_features INTEGER NOT NULL,
      similarity REAL);
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
    CREATE TABLE IF NOT EXISTS signatures (
      node_id INTEGER PRIMARY KEY NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      keypoints BLOB NOT NULL,
      descriptors BLOB NOT NULL,
      appearance_width INTEGER NOT NULL,
      appearance_height INTEGER NOT NULL,
      appearance BLOB NOT NULL,
      crc32 INTEGER NOT NULL,
      descriptor_coding INTEGER NOT NULL DEFAULT 0);
    CREATE TABLE IF NOT EXISTS node_features (
      node_id INTEGER PRIMARY KEY NOT NULL REFERENCES nodes(node_id) ON DELETE CASCADE,
      features BLOB NOT NULL,
      crc32 INTEGER NOT NULL);
    CREATE TABLE IF NOT EXISTS arc_point_lists (
      arc_id INTEGER PRIMARY KEY NOT NULL REFERENCES arcs(arc_id) ON DELETE CASCADE,
      points BLOB NOT NULL,
      crc32 INTEGER NOT NULL);
  )sql");
}

void MapDatabase::UpgradeSchema() {
  if (schema_version_ >= kSchemaVersion) return;
  InTransaction([&] {
    if (schema_version_ < 2) {
      database_->Execute("ALTER TABLE nodes ADD COLUMN image_crc32 INTEGER;");
      // The checksums of the key-images already stored (CheckIntegrity read them whole before).
      std::vector<std::pair<int64_t, uint32_t>> checksums;
      SqliteStatement& images = database_->Prepare("SELECT node_id, image FROM nodes WHERE image IS NOT NULL;");
      while (images.Step()) {
        const std::vector<uint8_t> bytes = images.ColumnBlob(1);
        checksums.emplace_back(images.ColumnInt(0), Crc32(bytes.data(), bytes.size()));
      }
      images.Reset();
      SqliteStatement& update = database_->Prepare("UPDATE nodes SET image_crc32 = ? WHERE node_id = ?;");
      for (const auto& [node, crc] : checksums) update.Bind(1, int64_t{crc}).Bind(2, node).Run();
    }
    if (schema_version_ < 3) {
      database_->Execute("ALTER TABLE nodes ADD COLUMN route INTEGER NOT NULL DEFAULT 0;");
      database_->Execute("ALTER TABLE arcs ADD COLUMN similarity REAL;");
    }
    // 4 adds the signatures table, 6 the blob tables (the rows of the tables before them stay, and are read), 7
    // the signatures' descriptor coding (their rows stay verbatim).
    if (schema_version_ >= 4 && schema_version_ < 7) {
      SqliteStatement& column =
          database_->Prepare("SELECT COUNT(*) FROM pragma_table_info('signatures') WHERE name = 'descriptor_coding';");
      const bool present = column.Step() && column.ColumnInt(0) > 0;
      column.Reset();
      if (!present) {
        database_->Execute("ALTER TABLE signatures ADD COLUMN descriptor_coding INTEGER NOT NULL DEFAULT 0;");
      }
    }
    if (schema_version_ < 6) CreateTables();
    // 5 changes no table: key-images may be stored at a reduced resolution, which older retraces cannot read.
    database_->Execute("PRAGMA user_version=" + std::to_string(kSchemaVersion) + ";");
  });
  schema_version_ = kSchemaVersion;
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
      node.image.empty()
          ? std::vector<uint8_t>()
          : EncodeImage(node.image, options_, /*allow_reduced=*/schema_version_ >= 5, path_.string());
  InTransaction([&] {
    // A map of an older schema opened for writing keeps its schema (UpgradeSchema() brings it up to date).
    const bool has_checksums = schema_version_ >= 2;
    const bool has_routes = schema_version_ >= 3;
    SqliteStatement& insert_node = database_->Prepare(
        has_routes      ? "INSERT INTO nodes (node_id, source_frame, image_name, timestamp, width, height, image, "
                          "image_crc32, route) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?);"
        : has_checksums ? "INSERT INTO nodes (node_id, source_frame, image_name, timestamp, width, height, image, "
                          "image_crc32) VALUES (?, ?, ?, ?, ?, ?, ?, ?);"
                        : "INSERT INTO nodes (node_id, source_frame, image_name, timestamp, width, height, image) "
                          "VALUES (?, ?, ?, ?, ?, ?, ?);");
    insert_node.Bind(1, int64_t{node.id})
        .Bind(2, int64_t{node.source_frame})
        .Bind(3, node.image_name)
        .Bind(4, node.timestamp)
        .Bind(5, int64_t{node.image.cols})
        .Bind(6, int64_t{node.image.rows});
    if (image.empty()) {
      insert_node.BindNull(7);
      if (has_checksums) insert_node.BindNull(8);
    } else {
      insert_node.BindBlob(7, image.data(), image.size());
      if (has_checksums) insert_node.Bind(8, int64_t{Crc32(image.data(), image.size())});
    }
    if (has_routes) insert_node.Bind(9, int64_t{node.route});
    insert_node.Run();
    WriteObservations(node.id, node.features);
    if (!node.signature.empty() && schema_version_ >= 4) WriteSignature(node.id, node.signature);
  });
}

void MapDatabase::WriteSignature(node_t node, const KeyImageSignature& signature) {
  if (schema_version_ < 4) throw InputError(path_.string(), "a map of schema < 4 cannot store signatures");
  const KeyImageSignature& s = signature;
  const size_t descriptor_bytes = static_cast<size_t>(s.descriptors.cols);
  if (s.descriptors.type() != CV_8UC1 || descriptor_bytes % 8 != 0 || descriptor_bytes > kMaxDescriptorBytes ||
      (!s.keypoints.empty() && descriptor_bytes == 0) || s.descriptors.rows != static_cast<int>(s.keypoints.size()) ||
      s.appearance.type() != CV_8UC1 || s.appearance.empty()) {
    throw std::invalid_argument(
        "WriteSignature: needs descriptors of 8, 16, 24 or 32 bytes, one per key-point, and an appearance");
  }
  const std::vector<uint8_t> keypoints = EncodeKeypoints(s.keypoints, path_.string());
  const std::vector<uint8_t> appearance = MatBytes(s.appearance);
  // The differences from what the stored key-image predicts, when it is stored and a prediction is set.
  int64_t coding = kDescriptorsVerbatim;
  std::vector<uint8_t> descriptors;
  if (descriptor_prediction_ && schema_version_ >= 7 && !s.keypoints.empty()) {
    SqliteStatement& stored = database_->Prepare("SELECT image IS NOT NULL FROM nodes WHERE node_id = ?;");
    stored.Bind(1, int64_t{node});
    const bool has_image = stored.Step() && stored.ColumnInt(0) != 0;
    stored.Reset();
    if (has_image) {
      const cv::Mat predicted = descriptor_prediction_(ReadKeyImage(node), StoredKeypoints(keypoints));
      if (predicted.type() != CV_8UC1 || predicted.rows != s.descriptors.rows || predicted.cols != s.descriptors.cols) {
        throw std::invalid_argument("WriteSignature: the descriptor prediction has another size than the descriptors");
      }
      descriptors = EncodeDescriptorResidual(s.descriptors, predicted);
      coding = kDescriptorDifferences;
    }
  }
  if (coding == kDescriptorsVerbatim) descriptors = MatBytes(s.descriptors);
  // A null pointer would bind SQL NULL; a key-image without key-points (a blank image) stores an empty blob.
  static const uint8_t kNothing = 0;
  const auto data = [](const std::vector<uint8_t>& v) -> const void* { return v.empty() ? &kNothing : v.data(); };
  InTransaction([&] {
    SqliteStatement& insert =
        database_
            ->Prepare(schema_version_ >= 7
                          ? "INSERT OR REPLACE INTO signatures (node_id, keypoints, descriptors, appearance_width, "
                            "appearance_height, appearance, crc32, descriptor_coding) VALUES (?, ?, ?, ?, ?, ?, ?, ?);"
                          : "INSERT OR REPLACE INTO signatures (node_id, keypoints, descriptors, appearance_width, "
                            "appearance_height, appearance, crc32) VALUES (?, ?, ?, ?, ?, ?, ?);")
            .Bind(1, int64_t{node})
            .BindBlob(2, data(keypoints), keypoints.size())
            .BindBlob(3, data(descriptors), descriptors.size())
            .Bind(4, int64_t{s.appearance.cols})
            .Bind(5, int64_t{s.appearance.rows})
            .BindBlob(6, appearance.data(), appearance.size())
            .Bind(7, int64_t{SignatureCrc32(keypoints, descriptors, appearance)});
    if (schema_version_ >= 7) insert.Bind(8, coding);
    insert.Run();
  });
}

void MapDatabase::WriteObservations(node_t node, const std::vector<FeatureObservation>& features) {
  if (schema_version_ >= 6) {
    InTransaction([&] {
      // Added to the node's blob, if it has one already.
      std::vector<FeatureObservation> all;
      SqliteStatement& stored = database_->Prepare("SELECT features FROM node_features WHERE node_id = ?;");
      stored.Bind(1, int64_t{node});
      if (stored.Step()) {
        if (const auto fault = DecodeFeatures(stored.ColumnBlob(0), &all)) {
          stored.Reset();
          throw InputError(path_.string(), kCorrupt + fmt::format("features of node {}: {}", node, *fault));
        }
      }
      stored.Reset();
      // A map upgraded from schema < 6 keeps its rows: a feature there must not be stored again (ReadMap would
      // refuse the map; the rows' primary key refused it here before).
      // One query for the node's rows (none in a map written with schema 6).
      std::unordered_set<feature_t> in_rows;
      SqliteStatement& rows = database_->Prepare("SELECT feature_id FROM observations WHERE node_id = ?;");
      rows.Bind(1, int64_t{node});
      while (rows.Step()) in_rows.insert(rows.ColumnInt(0));
      rows.Reset();
      for (const FeatureObservation& f : features) {
        if (in_rows.count(f.feature_id) > 0) {
          throw InputError(path_.string(),
                           fmt::format("features of node {} cannot be stored: feature {} is stored already", node,
                                       f.feature_id));
        }
      }
      all.insert(all.end(), features.begin(), features.end());
      std::vector<uint8_t> bytes;
      try {
        bytes = EncodeFeatures(std::move(all));
      } catch (const std::invalid_argument& e) {
        throw InputError(path_.string(), fmt::format("features of node {} cannot be stored: {}", node, e.what()));
      }
      InsertChecksummedBlob(database_.get(),
                            "INSERT OR REPLACE INTO node_features (node_id, features, crc32) VALUES (?, ?, ?);", node,
                            bytes);
    });
    return;
  }
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
    const bool has_similarity = schema_version_ >= 3;
    SqliteStatement& insert_arc = database_->Prepare(
        has_similarity ? "INSERT INTO arcs (arc_id, from_node, to_node, kind, rotation, translation, sigma_p, "
                         "num_features, similarity) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?);"
                       : "INSERT INTO arcs (arc_id, from_node, to_node, kind, rotation, translation, sigma_p, "
                         "num_features) VALUES (?, ?, ?, ?, ?, ?, ?, ?);");
    if (has_similarity) {
      if (arc.similarity) {
        insert_arc.Bind(9, *arc.similarity);
      } else {
        insert_arc.BindNull(9);
      }
    }
    insert_arc.Bind(1, int64_t{arc.id})
        .Bind(2, int64_t{arc.from})
        .Bind(3, int64_t{arc.to})
        .Bind(4, arc.kind)
        .BindBlob(5, rotation.data(), 9 * sizeof(double))
        .BindBlob(6, t.data(), 3 * sizeof(double))
        .Bind(7, arc.sigma_p)
        .Bind(8, static_cast<int64_t>(arc.points.size()))
        .Run();
    if (schema_version_ >= 6) {
      std::vector<uint8_t> bytes;
      try {
        bytes = EncodeArcPoints(arc.points);
      } catch (const std::invalid_argument& e) {
        throw InputError(path_.string(), fmt::format("3D points of arc {} cannot be stored: {}", arc.id, e.what()));
      }
      InsertChecksummedBlob(database_.get(), "INSERT INTO arc_point_lists (arc_id, points, crc32) VALUES (?, ?, ?);",
                            arc.id, bytes);
      return;
    }
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

cv::Mat MapDatabase::ReadKeyImage(node_t id) {
  SqliteStatement& statement = database_->Prepare("SELECT width, height, image FROM nodes WHERE node_id = ?;");
  statement.Bind(1, id);
  const std::string name = fmt::format("key-image of node {}", id);
  const auto fail = [&](const std::string& fault) {
    statement.Reset();
    throw InputError(path_.string(), kCorrupt + fault);
  };
  if (!statement.Step()) fail(fmt::format("node {} is missing", id));
  if (statement.ColumnIsNull(2)) fail(name + " is missing");
  cv::Mat image;
  if (const auto fault =
          DecodeKeyImage(statement.ColumnBlob(2), statement.ColumnInt(0), statement.ColumnInt(1), name, &image)) {
    fail(*fault);
  }
  statement.Reset();
  return image;
}

KeyImageSignature MapDatabase::ReadSignature(node_t id) {
  KeyImageSignature signature;
  if (schema_version_ < 4) return signature;
  SqliteStatement& node = database_->Prepare("SELECT width, height FROM nodes WHERE node_id = ?;");
  node.Bind(1, id);
  const bool found = node.Step();
  const int64_t image_width = found ? node.ColumnInt(0) : 0, image_height = found ? node.ColumnInt(1) : 0;
  node.Reset();
  SqliteStatement& row = database_->Prepare(
      std::string("SELECT keypoints, descriptors, appearance_width, appearance_height, appearance, ") +
      (schema_version_ >= 7 ? "descriptor_coding" : "0") + " FROM signatures WHERE node_id = ?;");
  row.Bind(1, id);
  if (row.Step()) {
    const auto fault =
        DecodeSignature(row.ColumnBlob(0), row.ColumnBlob(1), row.ColumnInt(2), row.ColumnInt(3), row.ColumnBlob(4),
                        image_width, image_height, /*features=*/true, &signature, row.ColumnInt(5));
    row.Reset();
    if (fault) throw InputError(path_.string(), fmt::format("{}relocalization signature of node {} {}", kCorrupt, id,
                                                            *fault));
  }
  row.Reset();
  return signature;
}

Map MapDatabase::ReadMap(bool load_images, bool load_signature_features) {
  const std::string source = path_.string();
  // Every fault found while reading: the statement is reset first so the map can still be closed cleanly.
  const auto fail = [&](SqliteStatement& statement, const std::string& fault) {
    statement.Reset();
    throw InputError(source, kCorrupt + fault);
  };
  const auto finite = [](std::initializer_list<double> values) {
    return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
  };
  constexpr int64_t kMaxImageSide = 1 << 15;
  Map map;
  std::unordered_map<node_t, std::pair<int64_t, int64_t>> image_sizes;  // node id -> stored width, height
  SqliteStatement& nodes = database_->Prepare(
      schema_version_ >= 3
          ? "SELECT node_id, source_frame, image_name, timestamp, width, height, image, route FROM nodes "
            "ORDER BY node_id;"
          : "SELECT node_id, source_frame, image_name, timestamp, width, height, image FROM nodes ORDER BY node_id;");
  while (nodes.Step()) {
    MapNode node;
    node.id = nodes.ColumnInt(0);
    node.source_frame = nodes.ColumnInt(1);
    node.image_name = nodes.ColumnText(2);
    node.timestamp = nodes.ColumnDouble(3);
    const int64_t width = nodes.ColumnInt(4);
    const int64_t height = nodes.ColumnInt(5);
    const std::string name = fmt::format("key-image of node {}", node.id);
    if (map.FindNode(node.id) != nullptr) fail(nodes, fmt::format("node {} appears twice", node.id));
    if (!nodes.ColumnIsNull(6) && (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide)) {
      fail(nodes, fmt::format("{} has a size of {}x{}", name, width, height));
    }
    if (!finite({node.timestamp})) fail(nodes, fmt::format("node {} has no finite timestamp", node.id));
    if (schema_version_ >= 3) {
      const int64_t route = nodes.ColumnInt(7);
      if (route < 0 || route > 1000000) fail(nodes, fmt::format("node {} has route {}", node.id, route));
      node.route = static_cast<int>(route);
    }
    if (load_images) {
      if (nodes.ColumnIsNull(6)) fail(nodes, name + " is missing");
      if (const auto fault = DecodeKeyImage(nodes.ColumnBlob(6), width, height, name, &node.image)) {
        fail(nodes, *fault);
      }
    }
    image_sizes[node.id] = {width, height};
    map.AddNode(std::move(node));
  }
  nodes.Reset();

  // Features lie in their key-image (tracked positions may reach half a pixel beyond the border).
  const auto outside_key_image = [&](node_t node_id, const FeatureObservation& f) -> std::optional<std::string> {
    const auto [width, height] = image_sizes[node_id];
    if (!finite({f.position.x(), f.position.y()}) || f.position.x() < -1 || f.position.y() < -1 ||
        f.position.x() > width || f.position.y() > height) {
      return fmt::format("feature {} of node {} lies outside its {}x{} key-image", f.feature_id, node_id, width,
                         height);
    }
    return std::nullopt;
  };
  SqliteStatement& observations =
      database_->Prepare("SELECT node_id, feature_id, x, y, patch_size, patch FROM observations ORDER BY node_id;");
  while (observations.Step()) {
    FeatureObservation f;
    const node_t node_id = observations.ColumnInt(0);
    f.feature_id = observations.ColumnInt(1);
    f.position = Vector2d(observations.ColumnDouble(2), observations.ColumnDouble(3));
    MapNode* node = map.MutableNode(node_id);
    if (node == nullptr) fail(observations, fmt::format("features of missing node {}", node_id));
    if (const auto fault = outside_key_image(node_id, f)) fail(observations, *fault);
    const int64_t size = observations.ColumnInt(4);
    if (!observations.ColumnIsNull(5)) {
      const std::vector<uint8_t> bytes = observations.ColumnBlob(5);
      if (size <= 0 || size > 1024 || bytes.size() != static_cast<size_t>(size * size)) {
        fail(observations, fmt::format("reference patch of feature {} of node {}", f.feature_id, node_id));
      }
      f.patch = cv::Mat(static_cast<int>(size), static_cast<int>(size), CV_8UC1);
      std::copy(bytes.begin(), bytes.end(), f.patch.data);
    }
    node->features.push_back(std::move(f));
  }
  observations.Reset();
  if (schema_version_ >= 6) {
    SqliteStatement& blobs = database_->Prepare("SELECT node_id, features FROM node_features ORDER BY node_id;");
    std::vector<FeatureObservation> features;
    while (blobs.Step()) {
      const node_t node_id = blobs.ColumnInt(0);
      MapNode* node = map.MutableNode(node_id);
      if (node == nullptr) fail(blobs, fmt::format("features of missing node {}", node_id));
      if (const auto fault = DecodeFeatures(blobs.ColumnBlob(1), &features)) {
        fail(blobs, fmt::format("features of node {}: {}", node_id, *fault));
      }
      // A map upgraded from schema < 6 may hold rows of this node too (read above): no feature twice.
      std::unordered_set<feature_t> in_rows;
      for (const FeatureObservation& f : node->features) in_rows.insert(f.feature_id);
      for (FeatureObservation& f : features) {
        if (const auto fault = outside_key_image(node_id, f)) fail(blobs, *fault);
        if (in_rows.count(f.feature_id) > 0) {
          fail(blobs, fmt::format("feature {} of node {} is stored twice", f.feature_id, node_id));
        }
        node->features.push_back(std::move(f));
      }
    }
    blobs.Reset();
  }
  // push_back's growth leaves up to half of each list unused: 13 MB on a map of 1264 key-images.
  for (const MapNode& node : map.nodes()) map.MutableNode(node.id)->features.shrink_to_fit();

  if (schema_version_ >= 4) {
    SqliteStatement& signatures = database_->Prepare(
        std::string("SELECT node_id, keypoints, descriptors, appearance_width, appearance_height, appearance, ") +
        (schema_version_ >= 7 ? "descriptor_coding" : "0") + " FROM signatures;");
    while (signatures.Step()) {
      const node_t node_id = signatures.ColumnInt(0);
      MapNode* node = map.MutableNode(node_id);
      if (node == nullptr) fail(signatures, fmt::format("relocalization signature of missing node {}", node_id));
      const auto [image_width, image_height] = image_sizes[node_id];
      if (const auto fault =
              DecodeSignature(signatures.ColumnBlob(1), signatures.ColumnBlob(2), signatures.ColumnInt(3),
                              signatures.ColumnInt(4), signatures.ColumnBlob(5), image_width, image_height,
                              load_signature_features, &node->signature, signatures.ColumnInt(6))) {
        fail(signatures, fmt::format("relocalization signature of node {} {}", node_id, *fault));
      }
    }
    signatures.Reset();
  }

  SqliteStatement& arcs = database_->Prepare(
      schema_version_ >= 3
          ? "SELECT arc_id, from_node, to_node, kind, rotation, translation, sigma_p, similarity FROM arcs "
            "ORDER BY arc_id;"
          : "SELECT arc_id, from_node, to_node, kind, rotation, translation, sigma_p FROM arcs ORDER BY arc_id;");
  while (arcs.Step()) {
    MapArc arc;
    arc.id = arcs.ColumnInt(0);
    arc.from = arcs.ColumnInt(1);
    arc.to = arcs.ColumnInt(2);
    arc.kind = arcs.ColumnText(3);
    const std::string name = fmt::format("arc {}", arc.id);
    if (map.FindArc(arc.id) != nullptr) fail(arcs, name + " appears twice");
    if (map.FindNode(arc.from) == nullptr || map.FindNode(arc.to) == nullptr || arc.from == arc.to) {
      fail(arcs, fmt::format("{} joins nodes {} and {}", name, arc.from, arc.to));
    }
    const std::vector<uint8_t> rotation = arcs.ColumnBlob(4);
    const std::vector<uint8_t> translation = arcs.ColumnBlob(5);
    if (rotation.size() != 9 * sizeof(double) || translation.size() != 3 * sizeof(double)) {
      fail(arcs, "geometry of " + name + " has the wrong size");
    }
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> r;
    Vector3d t;
    std::memcpy(r.data(), rotation.data(), rotation.size());
    std::memcpy(t.data(), translation.data(), translation.size());
    arc.to_from_from.rotation = r;
    arc.to_from_from.translation = t;
    arc.sigma_p = arcs.ColumnDouble(6);
    // R is a rotation, t has unit length (the arc's unit), σ_p is a length in pixels.
    const bool is_rotation = r.allFinite() && (r * r.transpose() - Matrix3d::Identity()).norm() < 1e-6 &&
                             r.determinant() > 0;
    if (!is_rotation || !t.allFinite() || std::abs(t.norm() - 1.0) > 1e-6) {
      fail(arcs, "geometry of " + name + " is not a rotation and a unit translation");
    }
    if (!std::isfinite(arc.sigma_p) || arc.sigma_p < 0) {
      fail(arcs, fmt::format("sigma_p of {} is {}", name, arc.sigma_p));
    }
    if (schema_version_ >= 3 && !arcs.ColumnIsNull(7)) {
      arc.similarity = arcs.ColumnDouble(7);
      if (!(*arc.similarity >= 0.0 && *arc.similarity <= 1.0)) {
        fail(arcs, fmt::format("similarity of {} is {}, not in [0, 1]", name, *arc.similarity));
      }
    }
    map.AddArc(std::move(arc));
  }
  arcs.Reset();

  SqliteStatement& points = database_->Prepare("SELECT arc_id, feature_id, x, y, z FROM arc_points ORDER BY arc_id;");
  while (points.Step()) {
    const arc_t arc_id = points.ColumnInt(0);
    const ArcPoint point{points.ColumnInt(1),
                         Vector3d(points.ColumnDouble(2), points.ColumnDouble(3), points.ColumnDouble(4))};
    MapArc* arc = map.MutableArc(arc_id);
    if (arc == nullptr) fail(points, fmt::format("3D points of missing arc {}", arc_id));
    if (!point.point_in_from.allFinite()) {
      fail(points, fmt::format("3D point of feature {} of arc {} is not finite", point.feature_id, arc_id));
    }
    arc->points.push_back(point);
  }
  points.Reset();
  if (schema_version_ >= 6) {
    SqliteStatement& blobs = database_->Prepare("SELECT arc_id, points FROM arc_point_lists ORDER BY arc_id;");
    std::vector<ArcPoint> decoded;
    while (blobs.Step()) {
      const arc_t arc_id = blobs.ColumnInt(0);
      MapArc* arc = map.MutableArc(arc_id);
      if (arc == nullptr) fail(blobs, fmt::format("3D points of missing arc {}", arc_id));
      if (const auto fault = DecodeArcPoints(blobs.ColumnBlob(1), &decoded)) {
        fail(blobs, fmt::format("3D points of arc {}: {}", arc_id, *fault));
      }
      if (!arc->points.empty()) fail(blobs, fmt::format("3D points of arc {} are stored twice", arc_id));
      arc->points = std::move(decoded);
      decoded.clear();
    }
    blobs.Reset();
  }

  SqliteStatement& scales = database_->Prepare("SELECT node_id, arc_in, arc_out, scale FROM node_scales;");
  while (scales.Step()) {
    const NodeScale scale{scales.ColumnInt(0), scales.ColumnInt(1), scales.ColumnInt(2), scales.ColumnDouble(3)};
    const MapArc* in = map.FindArc(scale.arc_in);
    const MapArc* out = map.FindArc(scale.arc_out);
    if (in == nullptr || out == nullptr || in->to != scale.node || out->from != scale.node) {
      fail(scales, fmt::format("scale at node {} does not join arc {} to arc {} there", scale.node, scale.arc_in,
                               scale.arc_out));
    }
    if (!std::isfinite(scale.scale) || scale.scale <= 0) {
      fail(scales, fmt::format("scale at node {} between arcs {} and {} is {}", scale.node, scale.arc_in,
                               scale.arc_out, scale.scale));
    }
    map.AddScale(scale);
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

int64_t MapDatabase::SignatureBytes() {
  if (schema_version_ < 4) return 0;
  SqliteStatement& s = database_->Prepare(
      "SELECT COALESCE(SUM(LENGTH(keypoints) + LENGTH(descriptors) + LENGTH(appearance)), 0) FROM signatures;");
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

void MapDatabase::Close() {
  if (!database_) return;
  if (writable_) {
    database_->Execute("PRAGMA wal_checkpoint(TRUNCATE);");
    database_->Execute("PRAGMA journal_mode=DELETE;");
  }
  database_.reset();
  std::error_code ec;
  for (const auto& side : SideFiles(path_)) {
    if (std::filesystem::exists(side, ec)) {
      throw InputError(path_.string(), "the map's log was not folded into it (" + side.string() + " remains)");
    }
  }
}

std::filesystem::path StagedMap::StagingPathFor(const std::filesystem::path& path) {
  return path.string() + ".incomplete";
}

std::filesystem::path StagedMap::LockPathFor(const std::filesystem::path& path) { return path.string() + ".lock"; }

StagedMap::StagedMap(const std::filesystem::path& path, bool overwrite)
    : path_(path), staging_path_(StagingPathFor(path)), lock_path_(LockPathFor(path)), overwrite_(overwrite) {}

std::unique_ptr<StagedMap> StagedMap::Begin(const std::filesystem::path& path, const MapDatabaseOptions& options,
                                            bool overwrite) {
  const std::string source = path.string();
  std::string error;
  if (!options.Check(&error)) throw InputError(source, "bad map options: " + error);
  const auto check_destination = [&] {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return;
    if (!overwrite) throw InputError(source, "map file exists already (choose another name or overwrite)");
    MapDatabase::CheckReplaceable(path);
  };
  check_destination();
  std::error_code ec;
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  if (!std::filesystem::is_directory(folder, ec)) throw InputError(source, "no such folder: " + folder.string());
  std::unique_ptr<StagedMap> staged(new StagedMap(path, overwrite));

  staged->Lock();
  check_destination();  // again, now that no other writer can change it

  // A stale staging map of an interrupted teach is replaced (Create removes it and its side files).
  if (std::filesystem::exists(staged->staging_path_, ec)) MapDatabase::CheckReplaceable(staged->staging_path_);
  staged->database_ = MapDatabase::Create(staged->staging_path_, options, /*overwrite=*/true);
  staged->database_->SetMetadata(MapDatabase::kTeachStateKey, MapDatabase::kIncomplete);
  return staged;
}

void StagedMap::Lock() {
  const std::string source = path_.string();
  // The lock: a writer that finds the file locked fails at once; one that locked a file the holder removed
  // meanwhile (a finished writer removes it before unlocking) tries again with the new file.
  for (int attempt = 0; attempt < 100 && lock_fd_ < 0; ++attempt) {
    const int fd = open(lock_path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
      throw InputError(source, fmt::format("cannot create the lock file {}: {}", lock_path_.string(),
                                           std::strerror(errno)));
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int flock_error = errno;
      close(fd);
      if (flock_error == EWOULDBLOCK) {
        throw InputError(source, "another retrace teach is writing this map now (" + lock_path_.string() +
                                     " is locked); try again when it has finished");
      }
      throw InputError(source,
                       fmt::format("cannot lock {}: {}", lock_path_.string(), std::strerror(flock_error)));
    }
    struct stat by_descriptor {};
    struct stat by_path {};
    if (fstat(fd, &by_descriptor) == 0 && stat(lock_path_.c_str(), &by_path) == 0 &&
        by_descriptor.st_dev == by_path.st_dev && by_descriptor.st_ino == by_path.st_ino) {
      lock_fd_ = fd;
    } else {
      close(fd);
    }
  }
  if (lock_fd_ < 0) throw InputError(source, "cannot lock " + lock_path_.string());
}

std::unique_ptr<StagedMap> StagedMap::BeginAppend(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(source, "no such map to append to");
  std::unique_ptr<StagedMap> staged(new StagedMap(path, /*overwrite=*/true));
  staged->Lock();
  // Checked (and a log of a killed writer folded in) before it is copied; a map whose teach did not finish is not
  // built on (the appended map would be marked complete).
  if (!MapDatabase::Open(path)->complete()) {
    throw InputError(source, "incomplete map (its teach did not finish); teach it again before appending to it");
  }
  for (const auto& side : SideFiles(path)) {
    if (std::filesystem::exists(side, ec)) {
      throw InputError(source, "the map has a log beside it (" + side.string() + "); open it once with retrace inspect");
    }
  }
  if (std::filesystem::exists(staged->staging_path_, ec)) MapDatabase::CheckReplaceable(staged->staging_path_);
  RemoveSideFiles(staged->staging_path_);
  std::filesystem::copy_file(path, staged->staging_path_, std::filesystem::copy_options::overwrite_existing, ec);
  if (ec) throw InputError(source, "cannot copy it to " + staged->staging_path_.string() + ": " + ec.message());
  staged->database_ = MapDatabase::Open(staged->staging_path_, /*writable=*/true);
  staged->database_->database_->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;");
  staged->database_->UpgradeSchema();
  staged->database_->SetMetadata(MapDatabase::kTeachStateKey, MapDatabase::kIncomplete);
  return staged;
}

StagedMap::~StagedMap() {
  database_.reset();  // folds the log in when it can; the staging map stays, marked incomplete
  if (lock_fd_ >= 0) {
    unlink(lock_path_.c_str());
    close(lock_fd_);
  }
}

void StagedMap::Commit() {
  const std::string source = path_.string();
  database_->SetMetadata(MapDatabase::kTeachStateKey, MapDatabase::kComplete);
  database_->Close();
  database_.reset();
  SyncPath(staging_path_, /*directory=*/false);
  std::error_code ec;
  if (std::filesystem::exists(path_, ec)) {
    if (!overwrite_) throw InputError(source, "map file exists already (choose another name or overwrite)");
    MapDatabase::CheckReplaceable(path_);
  }
  // Side files of the old map would be taken for the new map's: remove them first (the old map stays whole:
  // it was closed by its writer, and a log of a killed writer was only ever in the staging map).
  RemoveSideFiles(path_);
  if (overwrite_) {
    if (std::rename(staging_path_.c_str(), path_.c_str()) != 0) {
      throw InputError(source,
                       fmt::format("cannot move {} into place: {}", staging_path_.string(), std::strerror(errno)));
    }
  } else {
    // Never replace a file that appeared meanwhile (file systems without RENAME_NOREPLACE: checked just before).
    int moved = renameat2(AT_FDCWD, staging_path_.c_str(), AT_FDCWD, path_.c_str(), RENAME_NOREPLACE);
    if (moved != 0 && (errno == EINVAL || errno == ENOSYS) && !std::filesystem::exists(path_, ec)) {
      moved = std::rename(staging_path_.c_str(), path_.c_str());
    }
    if (moved != 0 && errno == EEXIST) {
      throw InputError(source, "map file exists already (choose another name or overwrite)");
    }
    if (moved != 0) {
      throw InputError(source,
                       fmt::format("cannot move {} into place: {}", staging_path_.string(), std::strerror(errno)));
    }
  }
  const std::filesystem::path directory = path_.has_parent_path() ? path_.parent_path() : std::filesystem::path(".");
  SyncPath(directory, /*directory=*/true);
}

}  // namespace retrace
