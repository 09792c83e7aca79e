#pragma once

// Procedural textures for the built-in town, generated from a seed so that a fresh machine needs no image files.
//
// The point of the simulator is to feed a feature tracker (Harris corners, SIFT), so the textures carry the kind of
// structure real streets have: window frames and mullions, brick courses, door panels, shop signs with letter-like
// glyphs, paving slab joints, asphalt grain, foliage clusters. Everything is built from seeded value noise (a lattice
// of hashed random values, smoothly interpolated; fractal sums of octaves = fBm) and drawn shapes. The noise is
// periodic with the texture size so textures tile without seams.
//
// All functions return CV_32FC3 images in RGB order with linear reflectance in [0, 1]; `size_m` style comments give
// the real-world size one texture tile is meant to cover (the town maps them with that scale).

#include <cstdint>

#include <opencv2/core.hpp>

namespace retrace {

// Deterministic 64-bit hash (splitmix64 finalizer); the basis of every random choice in the simulator, so that a
// seed reproduces the same world and the same images on every machine.
// (Inline: the renderer hashes every pixel.)
inline uint64_t HashMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
inline uint64_t HashCombine(uint64_t a, uint64_t b) {
  return HashMix(a ^ (HashMix(b) + 0x632be59bd9b4e019ULL + (a << 6)));
}
// Uniform in [0, 1) from a hash value.
double HashToUnit(uint64_t h);

// A small deterministic random generator (splitmix64 sequence).
class SimRandom {
 public:
  explicit SimRandom(uint64_t seed) : state_(HashMix(seed ^ 0x5bd1e995ULL)) {}
  uint64_t Next() { return HashMix(state_ += 0x9e3779b97f4a7c15ULL); }
  double Uniform() { return HashToUnit(Next()); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  int Int(int lo, int hi_inclusive) { return lo + static_cast<int>(Uniform() * (hi_inclusive - lo + 1)); }
  bool Chance(double p) { return Uniform() < p; }
  // Standard normal (Box-Muller).
  double Normal();

 private:
  uint64_t state_;
};

// Periodic value noise in [0, 1] at (x, y) in lattice units; the lattice repeats every `period_x` x `period_y` cells.
float PeriodicValueNoise(float x, float y, int period_x, int period_y, uint64_t seed);
// Fractal sum of `octaves` octaves of periodic value noise, in [0, 1]; base lattice `cells_x` x `cells_y` across
// the texture, (u, v) in [0, 1).
float PeriodicFbm(float u, float v, int cells_x, int cells_y, int octaves, uint64_t seed);

// Facade of upper floors: 4 window bays x 3 floors, 12 m x 9 m. `style` 0..3 picks brick or plaster and window
// kinds; the seed varies colours, shutters, curtains and balconies.
cv::Mat MakeFacadeTexture(int style, uint64_t seed);
// Ground floor with shop fronts, doors and signs with glyphs: 12 m x 4 m.
cv::Mat MakeShopfrontTexture(uint64_t seed);
// Asphalt with grain, patches and cracks: 8 m x 8 m.
cv::Mat MakeAsphaltTexture(uint64_t seed);
// Paving slabs (0.5 m) with joints and stains: 4 m x 4 m.
cv::Mat MakeSidewalkTexture(uint64_t seed);
// Grass with clover-like speckle: 4 m x 4 m.
cv::Mat MakeGrassTexture(uint64_t seed);
// Foliage clusters with dark gaps: 3 m x 3 m.
cv::Mat MakeFoliageTexture(uint64_t seed);
// Bark with vertical furrows: 1 m x 2 m.
cv::Mat MakeBarkTexture(uint64_t seed);
// Flat roof gravel: 8 m x 8 m.
cv::Mat MakeRoofTexture(uint64_t seed);
// Mostly uniform paint with a little grime, mid-grey (tinted by the material colour): 2 m x 2 m.
cv::Mat MakePaintTexture(uint64_t seed);
// Dark glass with a sky reflection gradient: 2 m x 1 m.
cv::Mat MakeGlassTexture(uint64_t seed);
// Clothes / body pattern for pedestrians: 1 m x 2 m (stripes, checks).
cv::Mat MakeClothTexture(uint64_t seed);

}  // namespace retrace
