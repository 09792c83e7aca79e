#include "retrace/map/descriptor_coding.h"

#include <stdexcept>

#include <fmt/format.h>

namespace retrace {

namespace {

constexpr uint8_t kVerbatim = 255;  // the descriptor follows itself

bool ValidLength(int bytes) { return bytes >= 8 && bytes <= 32 && bytes % 8 == 0; }

}  // namespace

std::vector<uint8_t> EncodeDescriptorResidual(const cv::Mat& descriptors, const cv::Mat& predicted) {
  if (descriptors.type() != CV_8UC1 || predicted.type() != CV_8UC1 || descriptors.size() != predicted.size() ||
      (descriptors.rows > 0 && !ValidLength(descriptors.cols))) {
    throw std::invalid_argument(
        "EncodeDescriptorResidual: needs descriptors and predictions of 8-32 bytes, one per row");
  }
  const int bytes = descriptors.rows > 0 ? descriptors.cols : 32;
  std::vector<uint8_t> code = {static_cast<uint8_t>(bytes)};
  std::vector<uint8_t> positions;
  for (int row = 0; row < descriptors.rows; ++row) {
    const uint8_t* d = descriptors.ptr<uint8_t>(row);
    const uint8_t* p = predicted.ptr<uint8_t>(row);
    positions.clear();
    for (int byte = 0; byte < bytes; ++byte) {
      for (uint8_t diff = d[byte] ^ p[byte]; diff != 0; diff &= diff - 1) {
        positions.push_back(static_cast<uint8_t>(8 * byte + __builtin_ctz(diff)));
      }
    }
    if (positions.size() >= static_cast<size_t>(bytes)) {
      code.push_back(kVerbatim);
      code.insert(code.end(), d, d + bytes);
    } else {
      code.push_back(static_cast<uint8_t>(positions.size()));
      code.insert(code.end(), positions.begin(), positions.end());
    }
  }
  return code;
}

namespace {

// Walks `code`; with `predicted` and `descriptors` set, also writes the descriptors.
std::optional<std::string> WalkCode(const std::vector<uint8_t>& code, size_t count, const cv::Mat* predicted,
                                    cv::Mat* descriptors, int* descriptor_bytes) {
  if (code.empty()) return std::string("has an empty descriptor code");
  const int bytes = code[0];
  if (!ValidLength(bytes)) return fmt::format("has a descriptor code of {}-byte descriptors", bytes);
  if (descriptor_bytes != nullptr) *descriptor_bytes = bytes;
  if (predicted != nullptr && count > 0 &&
      (predicted->type() != CV_8UC1 || predicted->rows != static_cast<int>(count) || predicted->cols != bytes)) {
    return fmt::format("has {} descriptors of {} bytes where {} of {} were predicted", count, bytes, predicted->rows,
                       predicted->cols);
  }
  if (descriptors != nullptr) *descriptors = predicted != nullptr ? predicted->clone() : cv::Mat();
  size_t at = 1;
  for (size_t row = 0; row < count; ++row) {
    if (at >= code.size()) return fmt::format("has a descriptor code that ends at key-point {} of {}", row, count);
    const uint8_t n = code[at++];
    uint8_t* d =
        descriptors != nullptr && !descriptors->empty() ? descriptors->ptr<uint8_t>(static_cast<int>(row)) : nullptr;
    if (n == kVerbatim) {
      if (at + bytes > code.size()) return fmt::format("has a descriptor code that ends at key-point {}", row);
      if (d != nullptr) std::copy(code.begin() + at, code.begin() + at + bytes, d);
      at += bytes;
      continue;
    }
    if (n >= bytes || at + n > code.size()) return fmt::format("has a bad descriptor code at key-point {}", row);
    int previous = -1;
    for (int i = 0; i < n; ++i) {
      const int bit = code[at + i];
      if (bit <= previous || bit >= 8 * bytes) return fmt::format("has a bad descriptor code at key-point {}", row);
      previous = bit;
      if (d != nullptr) d[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    }
    at += n;
  }
  if (at != code.size()) return fmt::format("has {} bytes after its {} descriptors' code", code.size() - at, count);
  return std::nullopt;
}

}  // namespace

std::optional<std::string> CheckDescriptorResidual(const std::vector<uint8_t>& code, size_t count,
                                                   int* descriptor_bytes) {
  return WalkCode(code, count, nullptr, nullptr, descriptor_bytes);
}

std::optional<std::string> DecodeDescriptorResidual(const std::vector<uint8_t>& code, const cv::Mat& predicted,
                                                    cv::Mat* descriptors) {
  return WalkCode(code, static_cast<size_t>(predicted.rows), &predicted, descriptors, nullptr);
}

}  // namespace retrace
