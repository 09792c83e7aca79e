#pragma once

// Test and benchmark support: maps of a straight route without images or geometry, enough for the place belief.

#include <vector>

#include "retrace/map/map.h"

namespace retrace {

// A linear route of `arcs` arcs (nodes 0..arcs, arc k from node k to k + 1, taught `frames_per_arc` frames apart),
// with the stored relative scale `scales[k]` at node k + 1 (ℓ_{k+1} = s ℓ_k) when given.
inline Map LinearMap(int arcs, const std::vector<double>& scales = {}, int frames_per_arc = 10) {
  Map map;
  for (int i = 0; i <= arcs; ++i) {
    MapNode node;
    node.id = i;
    node.source_frame = frames_per_arc * i;
    map.AddNode(node);
  }
  for (int k = 0; k < arcs; ++k) {
    MapArc arc;
    arc.id = k;
    arc.from = k;
    arc.to = k + 1;
    map.AddArc(arc);
  }
  for (size_t k = 0; k < scales.size(); ++k) {
    map.AddScale({static_cast<node_t>(k + 1), static_cast<arc_t>(k), static_cast<arc_t>(k + 1), scales[k]});
  }
  return map;
}

}  // namespace retrace
