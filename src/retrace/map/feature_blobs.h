#pragma once

// The byte layout of a key-image's features and an arc's 3D points in a map of schema >= 6 (map_database.h): one
// blob per key-image and one per arc instead of one table row per feature and per point (issue 16, map size).
//
// A row of SQLite costs its header, its keys and 8 bytes per REAL: 28 bytes per feature and 42 per point, 208 kB of
// kitti07's 1.06 MB map (3783 features, 2408 points). In a blob, features and points are sorted by feature id and
// each id is stored as its difference from the one before (LEB128: one or two bytes as the ids of one key-image lie
// close together), positions as 32-bit floats: 7 significant digits, 1e-4 px in a 1226 px key-image, a relative
// 6e-8 of a point's distance, far below what the tracker and the geometry resolve.
//
//   features: per feature  varint id delta, float32 x, float32 y, varint patch side s, s * s bytes of patch
//   points:   per point    varint id delta, float32 x, float32 y, float32 z
//
// Little-endian, whatever the machine. The decoders check the layout and report what is wrong instead of reading
// past the end; the map's checksum of the blob (map_database.cc) finds damage that leaves the layout intact.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "retrace/map/map.h"

namespace retrace {

// The features' bytes, sorted by feature id. Throws std::invalid_argument for a negative or repeated feature id or a
// patch that is not square 8-bit gray.
std::vector<uint8_t> EncodeFeatures(std::vector<FeatureObservation> features);
// The features of `bytes` (sorted by feature id), or why they cannot be read.
std::optional<std::string> DecodeFeatures(const std::vector<uint8_t>& bytes, std::vector<FeatureObservation>* features);

// The points' bytes, sorted by feature id. Throws std::invalid_argument for a negative or repeated feature id.
std::vector<uint8_t> EncodeArcPoints(std::vector<ArcPoint> points);
// The points of `bytes` (sorted by feature id), or why they cannot be read.
std::optional<std::string> DecodeArcPoints(const std::vector<uint8_t>& bytes, std::vector<ArcPoint>* points);

}  // namespace retrace
