// Unit tests of the map graph's queries (the store is tested in map_database_test).

#include "retrace/map/map.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

// A route taught in two pieces with a gap teach could not bridge: key-images 0-1-2 (arcs 0, 1), key-image 3 made in
// the gap (no arc), key-images 4-5-6 (arcs 2, 3); `source_frame` 10 frames apart. A second route (key-images 7-8,
// arc 4) taught later, and a join (a link, not a driven arc) from its key-image 7 to key-image 1.
Map TwoPieces() {
  Map map;
  for (int i = 0; i <= 8; ++i) {
    MapNode node;
    node.id = i;
    node.route = i <= 6 ? 0 : 1;
    node.source_frame = 10 * (i <= 6 ? i : i - 7);
    map.AddNode(node);
  }
  const auto add_arc = [&map](arc_t id, node_t from, node_t to, const char* kind) {
    MapArc arc;
    arc.id = id;
    arc.from = from;
    arc.to = to;
    arc.kind = kind;
    map.AddArc(arc);
  };
  add_arc(5, 7, 1, "join");  // first in insertion order: ArcsTo(1) lists it before arc 0
  add_arc(0, 0, 1, "tracking");
  add_arc(1, 1, 2, "tracking");
  add_arc(2, 4, 5, "tracking");
  add_arc(3, 5, 6, "matching");
  add_arc(4, 7, 8, "tracking");
  return map;
}

TEST(Map, DrivenArcAcrossGapFindsTheNextPieceInTheTeachDrivesOrder) {
  const Map map = TwoPieces();
  // From the first piece's end over the gap key-image 3 (no arc) to the arc leaving key-image 4.
  EXPECT_EQ(map.DrivenArcAcrossGap(2, +1), 2);
  // Back from the second piece's start to the arc entering key-image 2.
  EXPECT_EQ(map.DrivenArcAcrossGap(4, -1), 1);
  // The route's ends: nothing beyond (key-images of route 1 are not part of route 0's drive).
  EXPECT_EQ(map.DrivenArcAcrossGap(6, +1), kInvalidArcId);
  EXPECT_EQ(map.DrivenArcAcrossGap(0, -1), kInvalidArcId);
  // Route 1 has no key-image before 7, and no arc enters 7.
  EXPECT_EQ(map.DrivenArcAcrossGap(7, -1), kInvalidArcId);
  EXPECT_EQ(map.DrivenArcAcrossGap(8, -1), kInvalidArcId);
  // Within a piece: the driven arc leaving the next key-image, the one entering the previous (not the join).
  EXPECT_EQ(map.DrivenArcAcrossGap(0, +1), 1);
  EXPECT_EQ(map.DrivenArcAcrossGap(2, -1), 0);
  // No such node, no direction.
  EXPECT_EQ(map.DrivenArcAcrossGap(42, +1), kInvalidArcId);
  EXPECT_EQ(map.DrivenArcAcrossGap(2, 0), kInvalidArcId);
}

}  // namespace
}  // namespace retrace
