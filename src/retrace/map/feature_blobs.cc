#include "retrace/map/feature_blobs.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

namespace retrace {
namespace {

constexpr int64_t kMaxPatchSide = 1024;
constexpr feature_t kFeatureIdLimit = feature_t{1} << 62;  // ids stored are below it

class ByteWriter {
 public:
  void Varint(uint64_t value) {
    while (value >= 0x80) {
      bytes_.push_back(static_cast<uint8_t>(value | 0x80));
      value >>= 7;
    }
    bytes_.push_back(static_cast<uint8_t>(value));
  }
  // False (and nothing written) for a value a 32-bit float cannot hold.
  [[nodiscard]] bool Float(double value) {
    const float f = static_cast<float>(value);
    if (!std::isfinite(f)) return false;
    uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    for (int shift = 0; shift < 32; shift += 8) bytes_.push_back(static_cast<uint8_t>(bits >> shift));
    return true;
  }
  void Bytes(const uint8_t* data, size_t size) { bytes_.insert(bytes_.end(), data, data + size); }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

// Reads what ByteWriter wrote; every read fails (returns false) rather than pass the end.
class ByteReader {
 public:
  explicit ByteReader(const std::vector<uint8_t>& bytes) : bytes_(bytes) {}
  bool AtEnd() const { return position_ == bytes_.size(); }
  bool Varint(uint64_t* value) {
    *value = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (position_ == bytes_.size()) return false;
      const uint8_t byte = bytes_[position_++];
      *value |= static_cast<uint64_t>(byte & 0x7F) << shift;
      if ((byte & 0x80) == 0) return true;
    }
    return false;  // more than 64 bits
  }
  bool Float(double* value) {
    if (bytes_.size() - position_ < 4) return false;
    uint32_t bits = 0;
    for (int i = 0; i < 4; ++i) bits |= static_cast<uint32_t>(bytes_[position_++]) << (8 * i);
    float f;
    std::memcpy(&f, &bits, sizeof f);
    *value = f;
    return std::isfinite(f);
  }
  bool Bytes(size_t size, uint8_t* out) {
    if (bytes_.size() - position_ < size) return false;
    std::copy(bytes_.begin() + position_, bytes_.begin() + position_ + size, out);
    position_ += size;
    return true;
  }

 private:
  const std::vector<uint8_t>& bytes_;
  size_t position_ = 0;
};

// Sorts `items` by feature id and checks that the ids are non-negative and distinct.
template <typename Item>
void SortByFeatureId(std::vector<Item>* items, const char* what) {
  std::sort(items->begin(), items->end(), [](const Item& a, const Item& b) { return a.feature_id < b.feature_id; });
  for (size_t i = 0; i < items->size(); ++i) {
    const feature_t id = (*items)[i].feature_id;
    if (id < 0 || id >= kFeatureIdLimit)
      throw std::invalid_argument(fmt::format("{}: feature id {} is out of range", what, id));
    if (i > 0 && id == (*items)[i - 1].feature_id) {
      throw std::invalid_argument(fmt::format("{}: feature {} appears twice", what, id));
    }
  }
}

// Writes `id` as its difference from `*previous` (-1 at the start: the id itself), and makes it the previous one.
void WriteFeatureId(ByteWriter* writer, feature_t id, feature_t* previous) {
  writer->Varint(static_cast<uint64_t>(*previous < 0 ? id : id - *previous));
  *previous = id;
}

// The next feature id of a list read so far (`*previous`: the last one, -1 at the start; it becomes the new one),
// or why it is wrong.
std::optional<std::string> ReadFeatureId(ByteReader* reader, size_t index, feature_t* previous, feature_t* id) {
  uint64_t delta = 0;
  if (!reader->Varint(&delta)) return fmt::format("end of data in the id of entry {}", index);
  // Every id after the first is larger than the one before (sorted, distinct), and all are below kFeatureIdLimit.
  const uint64_t base = *previous < 0 ? 0 : static_cast<uint64_t>(*previous);
  if ((*previous >= 0 && delta == 0) || delta >= static_cast<uint64_t>(kFeatureIdLimit) - base) {
    return fmt::format("entry {} has an invalid feature id", index);
  }
  *id = static_cast<feature_t>(base + delta);
  *previous = *id;
  return std::nullopt;
}

}  // namespace

std::vector<uint8_t> EncodeFeatures(std::vector<FeatureObservation> features) {
  SortByFeatureId(&features, "EncodeFeatures");
  ByteWriter writer;
  feature_t previous = -1;
  for (const FeatureObservation& f : features) {
    WriteFeatureId(&writer, f.feature_id, &previous);
    if (!writer.Float(f.position.x()) || !writer.Float(f.position.y())) {
      throw std::invalid_argument(
          fmt::format("EncodeFeatures: the position of feature {} is not storable", f.feature_id));
    }
    if (!f.patch.empty() &&
        (f.patch.type() != CV_8UC1 || f.patch.rows != f.patch.cols || f.patch.rows > kMaxPatchSide)) {
      throw std::invalid_argument(
          fmt::format("EncodeFeatures: the patch of feature {} is not square 8-bit gray", f.feature_id));
    }
    writer.Varint(static_cast<uint64_t>(f.patch.rows));
    if (!f.patch.empty()) {
      const cv::Mat patch = f.patch.isContinuous() ? f.patch : f.patch.clone();
      writer.Bytes(patch.data, patch.total());
    }
  }
  return writer.Take();
}

std::optional<std::string> DecodeFeatures(const std::vector<uint8_t>& bytes,
                                          std::vector<FeatureObservation>* features) {
  features->clear();
  ByteReader reader(bytes);
  feature_t previous = -1;
  while (!reader.AtEnd()) {
    const size_t index = features->size();
    FeatureObservation f;
    if (auto fault = ReadFeatureId(&reader, index, &previous, &f.feature_id)) return fault;
    double x = 0.0, y = 0.0;
    if (!reader.Float(&x) || !reader.Float(&y)) return fmt::format("feature {} has no finite position", f.feature_id);
    f.position = Vector2d(x, y);
    uint64_t side = 0;
    if (!reader.Varint(&side) || side > static_cast<uint64_t>(kMaxPatchSide)) {
      return fmt::format("feature {} has a bad patch size", f.feature_id);
    }
    if (side > 0) {
      f.patch = cv::Mat(static_cast<int>(side), static_cast<int>(side), CV_8UC1);
      if (!reader.Bytes(f.patch.total(), f.patch.data))
        return fmt::format("end of data in the patch of feature {}", f.feature_id);
    }
    features->push_back(std::move(f));
  }
  return std::nullopt;
}

std::vector<uint8_t> EncodeArcPoints(std::vector<ArcPoint> points) {
  SortByFeatureId(&points, "EncodeArcPoints");
  ByteWriter writer;
  feature_t previous = -1;
  for (const ArcPoint& p : points) {
    WriteFeatureId(&writer, p.feature_id, &previous);
    for (int i = 0; i < 3; ++i) {
      if (!writer.Float(p.point_in_from[i])) {
        throw std::invalid_argument(
            fmt::format("EncodeArcPoints: the 3D point of feature {} is not storable", p.feature_id));
      }
    }
  }
  return writer.Take();
}

std::optional<std::string> DecodeArcPoints(const std::vector<uint8_t>& bytes, std::vector<ArcPoint>* points) {
  points->clear();
  ByteReader reader(bytes);
  feature_t previous = -1;
  while (!reader.AtEnd()) {
    ArcPoint p;
    if (auto fault = ReadFeatureId(&reader, points->size(), &previous, &p.feature_id)) return fault;
    for (int i = 0; i < 3; ++i) {
      if (!reader.Float(&p.point_in_from[i])) return fmt::format("3D point of feature {} is not finite", p.feature_id);
    }
    points->push_back(p);
  }
  return std::nullopt;
}

}  // namespace retrace
