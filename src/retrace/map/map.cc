#include "retrace/map/map.h"

#include <algorithm>
#include <stdexcept>

namespace retrace {

node_t Map::AddNode(MapNode node) {
  if (node.id == kInvalidNodeId) node.id = nodes_.empty() ? 0 : nodes_.back().id + 1;
  if (node_index_.count(node.id) != 0) throw std::invalid_argument("Map::AddNode: duplicate node id");
  node_index_[node.id] = nodes_.size();
  nodes_.push_back(std::move(node));
  visual_words_.reset();
  return nodes_.back().id;
}

arc_t Map::AddArc(MapArc arc) {
  if (arc.id == kInvalidArcId) arc.id = arcs_.empty() ? 0 : arcs_.back().id + 1;
  if (arc_index_.count(arc.id) != 0) throw std::invalid_argument("Map::AddArc: duplicate arc id");
  arc_index_[arc.id] = arcs_.size();
  arcs_.push_back(std::move(arc));
  return arcs_.back().id;
}

void Map::AddScale(const NodeScale& scale) { scales_.push_back(scale); }

const MapNode* Map::FindNode(node_t id) const {
  const auto it = node_index_.find(id);
  return it == node_index_.end() ? nullptr : &nodes_[it->second];
}

const MapArc* Map::FindArc(arc_t id) const {
  const auto it = arc_index_.find(id);
  return it == arc_index_.end() ? nullptr : &arcs_[it->second];
}

MapNode* Map::MutableNode(node_t id) {
  visual_words_.reset();
  return const_cast<MapNode*>(FindNode(id));
}

MapArc* Map::MutableArc(arc_t id) { return const_cast<MapArc*>(FindArc(id)); }

std::vector<const MapArc*> Map::ArcsFrom(node_t node) const {
  std::vector<const MapArc*> result;
  for (const MapArc& arc : arcs_) {
    if (arc.from == node) result.push_back(&arc);
  }
  return result;
}

std::vector<const MapArc*> Map::ArcsTo(node_t node) const {
  std::vector<const MapArc*> result;
  for (const MapArc& arc : arcs_) {
    if (arc.to == node) result.push_back(&arc);
  }
  return result;
}

arc_t Map::DrivenArcAcrossGap(node_t node, int direction) const {
  const MapNode* from = FindNode(node);
  if (from == nullptr || direction == 0) return kInvalidArcId;
  const MapNode* best = nullptr;
  arc_t best_arc = kInvalidArcId;
  for (const MapNode& other : nodes_) {
    if (other.route != from->route || (other.source_frame - from->source_frame) * direction <= 0) continue;
    if (best != nullptr && (other.source_frame - best->source_frame) * direction >= 0) continue;
    for (const MapArc* arc : direction > 0 ? ArcsFrom(other.id) : ArcsTo(other.id)) {
      if (arc->IsLink()) continue;
      best = &other;
      best_arc = arc->id;
      break;
    }
  }
  return best_arc;
}

std::optional<double> Map::ScaleAt(node_t node, arc_t arc_in, arc_t arc_out) const {
  for (const NodeScale& s : scales_) {
    if (s.node == node && s.arc_in == arc_in && s.arc_out == arc_out) return s.scale;
  }
  return std::nullopt;
}

feature_t Map::MaxFeatureId() const {
  feature_t max_id = kInvalidFeatureId;
  for (const MapNode& node : nodes_) {
    for (const FeatureObservation& f : node.features) max_id = std::max(max_id, f.feature_id);
  }
  return max_id;
}

cv::Mat Map::KeyImage(node_t id) const {
  const MapNode* node = FindNode(id);
  if (node == nullptr) return cv::Mat();
  if (!node->image.empty() || !key_image_loader_) return node->image;
  return key_image_loader_(id);
}

KeyImageSignature Map::Signature(node_t id) const {
  const MapNode* node = FindNode(id);
  if (node == nullptr) return KeyImageSignature();
  if (!node->signature.descriptors.empty() || !signature_loader_) return node->signature;
  return signature_loader_(id);
}

bool Map::HasKeyImage(node_t id) const {
  const MapNode* node = FindNode(id);
  return node != nullptr && (!node->image.empty() || key_image_loader_);
}

}  // namespace retrace
