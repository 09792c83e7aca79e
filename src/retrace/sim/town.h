#pragma once

// The built-in procedural town: a grid of streets with junctions, blocks of buildings with textured facades, shop
// fronts and signs, sidewalks with curbs, trees, street lamps, traffic signs, parked cars, road markings and
// crosswalks, parks, a surrounding ring of buildings, sky with clouds; pedestrians and cars moving on scripted paths.
// Everything follows from `seed`: the same options give the same town on every machine.
//
// Frame: X east, Y north, Z up (metres). Street centre lines run along x = street_x[i] and y = street_y[j]; the
// junction (i, j) is at (street_x[i], street_y[j]). Traffic drives on the right.

#include <cstdint>
#include <string>
#include <vector>

#include "retrace/sim/scene.h"
#include "retrace/util/types.h"

namespace retrace {

// Ranges of the fields: Scenario::Check (sim/scenario.h, ScenarioKeyRanges), the one place they are checked.
struct TownOptions {
  // Seed of every random choice (layout, buildings, textures, trees, cars, pedestrians).
  uint64_t seed = 1;
  // Number of blocks west-east and south-north (the route network has (blocks+1)^2 junctions).
  int blocks_x = 4;
  int blocks_y = 4;
  // Side length range of a block (between sidewalks), metres.
  double block_size_min = 35.0;
  double block_size_max = 55.0;
  // Width of the carriageway (two lanes) and of each sidewalk, metres; sidewalk height above the road.
  double road_width = 8.0;
  double sidewalk_width = 2.5;
  double sidewalk_height = 0.15;
  // Probability that an inner block is a park with trees instead of buildings.
  double park_probability = 0.12;
  // Floors above the 4 m ground floor (3 m each).
  int min_upper_floors = 1;
  int max_upper_floors = 5;
  // Mean spacing of street trees along sidewalks (0 = none), metres.
  double tree_spacing = 10.0;
  // Probability that a 6 m parking slot along a curb holds a car.
  double parked_car_probability = 0.35;
  // Moving occluders: pedestrians (walking around blocks and across streets) and cars (driving around blocks).
  int num_pedestrians = 12;
  int num_moving_cars = 4;
  // Optional folder of the user's photos (.jpg/.png): used as the facade textures of upper floors (each photo
  // covers 12 m of facade width) instead of the procedural facades. Empty = procedural only.
  std::string photo_folder;
};

struct TownLayout {
  std::vector<double> street_x;  // centre lines of the south-north streets
  std::vector<double> street_y;  // centre lines of the west-east streets
  double road_width = 8.0;
  double sidewalk_width = 2.5;

  // Centre of the right lane (metres right of the centre line).
  double lane_offset() const { return road_width / 4.0; }
  Vector2d Junction(int i, int j) const { return Vector2d(street_x[i], street_y[j]); }
  // Whether `p` lies on a street (carriageway or sidewalk) of the grid: within road_width / 2 + sidewalk_width of a
  // centre line and between the outermost streets' curbs. False inside a block and outside the town.
  bool OnStreets(const Vector2d& p) const;
};

// The streets of the town BuildTown builds from `options`, without building it (cheap: a few random draws).
TownLayout PlanTownLayout(const TownOptions& options);

// Builds the town into `scene` (textures, materials, static meshes, moving objects, sky) and commits it.
// Throws InputError when the photo folder is given but unreadable or holds no image.
TownLayout BuildTown(const TownOptions& options, Scene* scene);

// Escorts: people walking with the car close to the camera, the moving occluders of Booij 2007 §B.5.4 ("people
// walking next to and in front of the robot", at about 20 cm from it, blocking large parts of the panoramic view).
// Escort k stands at EscortSpot(k) of the carrier frame (Scene::SetCarrier: on the ground below the camera, x along
// its line of sight) and sways 5 cm sideways, bobs 3 cm and turns 6 degrees with its stride (1.0-1.2 s); height,
// clothes and phase are seeded. They are carried objects of the scene, never part of the static geometry.
constexpr int kMaxEscorts = 8;
// The spot of escort k (0..kMaxEscorts-1), metres in the carrier frame (x ahead, y left): 0.6 m left and right of
// the camera (k = 0, 1), 0.75 m ahead-left and ahead-right at 40 degrees (2, 3), 0.75 m behind-left and behind-right
// at 140 degrees (4, 5), 1 m straight ahead (6) and behind (7). Their bodies (0.6 m wide with the arms, 0.3 m deep)
// do not touch while they sway.
Vector2d EscortSpot(int k);
// Adds min(count, kMaxEscorts) escorts to `scene` as carried objects with materials of their own; seeded.
void AddEscorts(int count, uint64_t seed, Scene* scene);

// Routes through the town as lists of junctions, turned into the right lane by LaneRoute.
// A loop around the rectangle of blocks [i0, i1] x [j0, j1] (junction indices), counter-clockwise.
std::vector<Vector2d> LoopRouteJunctions(const TownLayout& layout, int i0, int j0, int i1, int j1);
// A figure eight over the 2 x 2 blocks whose south-west junction is (i0, j0), crossing itself at the junction
// (i0 + 1, j0 + 1): north through it, counter-clockwise around the north-west block, east through it, clockwise
// around the south-east block, back to the start (i0 + 1, j0). Eight junction-to-junction streets.
std::vector<Vector2d> FigureEightJunctions(const TownLayout& layout, int i0, int j0);
// A random drive of `num_segments` junction-to-junction segments from a junction near the south-west, without
// U-turns and preferring not to revisit streets; seeded.
std::vector<Vector2d> RandomRouteJunctions(const TownLayout& layout, int num_segments, uint64_t seed);
// Shifts a polyline of street centre points into the right lane (mitred corners): `offset` metres to the right
// of the direction of travel.
std::vector<Vector2d> OffsetPolyline(const std::vector<Vector2d>& points, double offset);

}  // namespace retrace
