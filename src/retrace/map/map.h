#pragma once

// The hybrid topological-geometric map (Segvic 2009 §3.2, design §1).
//
// Nodes are key-images. Each keeps its feature map: the 2D positions of point features in the key-image, indexed by
// globally unique feature ids; the tracker cuts each feature's reference appearance from the key-image itself,
// which the node stores.
// Arcs connect neighbouring nodes and carry the two-view geometry W_k of their two key-images: the relative motion
// (R, t) with t of unit length, the 3D points of the features seen in both nodes (the set M_k) in the unit scale of
// that arc, and the geometry's quality σ_p. Relative scales between the geometries of consecutive arcs are stored
// at their common node. No global metric consistency is kept: every arc has its own scale.
//
// The paper's graphs are linear or circular; this structure allows any graph (several routes, junctions, loops).

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/util/types.h"

namespace retrace {

// A feature as seen in one key-image.
struct FeatureObservation {
  feature_t feature_id = kInvalidFeatureId;
  Vector2d position = Vector2d::Zero();  // pixel position in the key-image
  // Reference appearance, 8-bit gray (e.g. 15x15), may be empty. retrace's teach leaves it empty: the key-image is
  // stored with its node, and repeat cuts the references from it at every pyramid level (stored patches only
  // duplicated those pixels, a third of a kitti07 map).
  cv::Mat patch;
};

// What relocalization needs of a key-image, computed once by teach and stored with it (design §6 bootstrap, issue
// 16): binary key-points for the verification by matching (feature/binary_features.h) and the key-image's quantised
// appearance thumbnail for retrieval (feature/global_descriptor.h). Empty in maps written before (schema < 4):
// repeat computes it when it loads such a map.
struct VisualWords;

struct KeyImageSignature {
  std::vector<cv::KeyPoint> keypoints;  // position (pt) and size; stored at 1/8 px
  cv::Mat descriptors;                  // CV_8U, one binary descriptor (8-32 bytes) per key-point, same order
  // ... or, as read from a map that stores them so (schema 7), their differences from the descriptors of the stored
  // key-image at these key-points (descriptor_coding.h), `descriptors` empty until the reader resolves them.
  std::vector<uint8_t> descriptor_residual;
  cv::Mat appearance;  // CV_8U quantised thumbnail (QuantizeGlobalDescriptor)

  bool empty() const { return descriptors.empty() && descriptor_residual.empty() && appearance.empty(); }
};

struct MapNode {
  node_t id = kInvalidNodeId;
  int64_t source_frame = -1;  // index of the key-image in the teach sequence
  std::string image_name;     // file name of the key-image in the teach sequence
  double timestamp = 0.0;
  // Which drive taught the key-image: 0 for the first, 1 for the first one appended (`teach --append`), ...
  int route = 0;
  cv::Mat image;  // the key-image itself (8-bit gray); may be left unloaded
  std::vector<FeatureObservation> features;
  KeyImageSignature signature;  // may be empty (maps of schema < 4)
};

// A feature of an arc's set M_k with its 3D reconstruction in the `from` key-image's camera frame.
struct ArcPoint {
  feature_t feature_id = kInvalidFeatureId;
  Vector3d point_in_from = Vector3d::Zero();
};

struct MapArc {
  arc_t id = kInvalidArcId;
  node_t from = kInvalidNodeId;
  node_t to = kInvalidNodeId;
  Rigid3d to_from_from;  // x_to = R x_from + t, |t| = 1 (the arc's unit of length)
  double sigma_p = 0.0;  // conservative reprojection error bound σ_p of W_k (Segvic 2009, eq. (6)), pixels
  std::vector<ArcPoint> points;
  std::string kind = "tracking";  // how the arc was made: tracking | matching | gap | loop | join
  // A link (loop, join): two images of one place related by wide-baseline matching, not a stretch driven.
  bool IsLink() const { return kind == "loop" || kind == "join"; }
  // Appearance similarity of the two key-images (Booij 2007 §B.2): epipolar-consistent correspondences over the
  // fewer features found in either image, in [0, 1]. For an arc made by tracking, the correspondences are the
  // tracked inliers of W_k and the features the corners tracked from each key-image; for an arc made by
  // wide-baseline matching (gap, loop, matching, join), the geometry's inlier matches and the wide-baseline
  // key-points of each image. Unknown (empty) for arcs of maps written before schema 3.
  std::optional<double> similarity;
  // The road plane between its key-images as repeat's metric path fits it (repeat/taught_path.h), when teach was
  // given the camera's height and stored it (LoadMapForLocalizer): camera b's height above the plane and its
  // standard deviation, in arc units; distance_b 0 when no plane was found. For the ground normal the map stores.
  struct GroundFit {
    double distance_b = 0.0;
    double distance_sigma = 0.0;
  };
  std::optional<GroundFit> ground_fit;

  size_t num_features() const { return points.size(); }
};

// Relative scale at a node between the geometries of the arc ending there and the arc starting there:
// a length expressed in units of `arc_out` is multiplied by `scale` to express it in units of `arc_in`.
struct NodeScale {
  node_t node = kInvalidNodeId;
  arc_t arc_in = kInvalidArcId;
  arc_t arc_out = kInvalidArcId;
  double scale = 1.0;
};

class Map {
 public:
  // Adds a node and returns its id (assigned here when node.id is invalid).
  node_t AddNode(MapNode node);
  arc_t AddArc(MapArc arc);
  void AddScale(const NodeScale& scale);

  const std::vector<MapNode>& nodes() const { return nodes_; }
  const std::vector<MapArc>& arcs() const { return arcs_; }
  const std::vector<NodeScale>& scales() const { return scales_; }
  MapNode* MutableNode(node_t id);
  MapArc* MutableArc(arc_t id);

  const MapNode* FindNode(node_t id) const;
  const MapArc* FindArc(arc_t id) const;
  // Arcs leaving / entering a node, in insertion order.
  std::vector<const MapArc*> ArcsFrom(node_t node) const;
  std::vector<const MapArc*> ArcsTo(node_t node) const;
  std::optional<double> ScaleAt(node_t node, arc_t arc_in, arc_t arc_out) const;
  // Across a gap teach could not bridge (a map in pieces): the driven arc (not a link) leaving the key-image of
  // `node`'s route that the teach drive made first after `node` among those such an arc leaves (direction +1), or
  // entering the one it made last before `node` among those such an arc enters (-1) — the start of the next piece
  // or the end of the previous one, in the order the drive made them (key-images made in the gap itself belong to
  // no arc). kInvalidArcId at a route's ends.
  arc_t DrivenArcAcrossGap(node_t node, int direction) const;

  // The largest feature id used so far (kInvalidFeatureId when there is none).
  feature_t MaxFeatureId() const;

  // Key-images kept out of memory (issue 16: 97 MB of decoded images on a map of 1264 key-images): a map read
  // without its images (MapDatabase::ReadMap(false)) is given a loader that decodes one on demand. KeyImage returns
  // the node's image when it holds one, else the loader's (not kept: callers cache what they derive from it), else
  // an empty image. The loader reports a key-image that cannot be read by throwing (InputError naming the map).
  using KeyImageLoader = std::function<cv::Mat(node_t)>;
  void SetKeyImageLoader(KeyImageLoader loader) { key_image_loader_ = std::move(loader); }
  cv::Mat KeyImage(node_t id) const;
  // The node holds its key-image or the loader can read it.
  bool HasKeyImage(node_t id) const;
  // The same for the key-points and descriptors of the relocalization signatures (MapDatabase::ReadMap with
  // load_signature_features false keeps only their appearance: 62 MB less on 1264 key-images). Signature returns
  // the node's signature when it holds its descriptors, else the loader's, else the node's.
  using SignatureLoader = std::function<KeyImageSignature(node_t)>;
  void SetSignatureLoader(SignatureLoader loader) { signature_loader_ = std::move(loader); }
  KeyImageSignature Signature(node_t id) const;

  // Retrieval by visual words (feature/visual_words.h) over the signatures' descriptors, entry i the i-th node: built
  // once for a map opened to localize in (LoadMapForLocalizer, or the first Localizer given the map) and shared by
  // its copies; AddNode and MutableNode drop it (the signatures it indexes may change).
  const std::shared_ptr<const VisualWords>& visual_words() const { return visual_words_; }
  void SetVisualWords(std::shared_ptr<const VisualWords> words) { visual_words_ = std::move(words); }

 private:
  std::vector<MapNode> nodes_;
  std::vector<MapArc> arcs_;
  std::vector<NodeScale> scales_;
  std::unordered_map<node_t, size_t> node_index_;
  std::unordered_map<arc_t, size_t> arc_index_;
  KeyImageLoader key_image_loader_;
  SignatureLoader signature_loader_;
  std::shared_ptr<const VisualWords> visual_words_;
};

}  // namespace retrace
