#pragma once

// What a person looks at after teach (Segvic 2009, Figs. 8-11; design §5 "map quality report"): features |M_k| and
// σ_p per arc, the spacing of key-images along the sequence, a contact sheet of the key-images, and the key-image
// poses seen from above, chained from the arc geometries and node scales and, when ground truth is given, aligned
// to it and drawn beside it.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "retrace/dataset/ground_truth.h"
#include "retrace/map/map.h"

namespace retrace {

struct KeyImagePose {
  node_t node = kInvalidNodeId;
  Rigid3d world_from_cam;  // world = the first node's camera frame, length unit = the first arc's baseline
};

// Poses of the key-images reachable from the first node, obtained by chaining the arc geometries (x_to = R x_from
// + t) and bringing each arc to the first arc's unit with the relative scales stored at the nodes (1 where a scale
// is missing). No global consistency is enforced by the map, so drift accumulates: this is for looking at.
std::vector<KeyImagePose> ChainKeyImagePoses(const Map& map);

struct MapStatistics {
  size_t num_nodes = 0;
  size_t num_arcs = 0;
  size_t num_features = 0;  // distinct feature ids over all key-images
  double median_arc_features = 0.0;
  double min_arc_features = 0.0;
  double median_sigma_p = 0.0;
  double max_sigma_p = 0.0;
  double median_frames_between_key_images = 0.0;
};

MapStatistics ComputeMapStatistics(const Map& map);

// Key-image positions in metres from ground truth (world_from_cam of every teach frame, indexed by source_frame),
// and the arc lengths between consecutive key-images. Nodes whose source frame has no pose are skipped.
double RouteLengthMetres(const Map& map, const std::vector<TimedPose>& ground_truth);

struct MapReportOptions {
  // Ground-truth poses of the (first) teach sequence, indexed by frame: the pose plot of route 0, bytes per metre.
  std::optional<std::vector<TimedPose>> ground_truth;
  // Threshold lines drawn in the plots: r_p for σ_p and n for the features per arc (0 = none).
  double sigma_p_threshold = 0.0;
  double min_features = 0.0;
  // Width of a key-image thumbnail in the contact sheet.
  int thumbnail_width = 240;
};

// Writes arcs.png, spacing.png, key_images.png and poses.png into `directory` (created when missing) and returns
// the paths written.
std::vector<std::filesystem::path> WriteMapReport(const Map& map, const std::filesystem::path& directory,
                                                  const MapReportOptions& options);

}  // namespace retrace
