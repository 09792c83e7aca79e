#include "retrace/sim/procedural_texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace retrace {
namespace {

using Rgb = cv::Vec3f;

float Clamp01(float x) { return std::min(1.0f, std::max(0.0f, x)); }

// Per-texel white noise in [-0.5, 0.5).
float TexelNoise(int x, int y, uint64_t seed) {
  return static_cast<float>(HashToUnit(HashCombine(seed, (static_cast<uint64_t>(y) << 32) ^ static_cast<uint32_t>(x)))) -
         0.5f;
}

Rgb Mix(const Rgb& a, const Rgb& b, float t) { return a * (1.0f - t) + b * t; }

Rgb Scale(const Rgb& c, float s) { return Rgb(c[0] * s, c[1] * s, c[2] * s); }

// Fills a rectangle (in pixels, right/bottom exclusive) with a colour modulated by fine noise.
void FillRect(cv::Mat& img, int x0, int y0, int x1, int y1, const Rgb& color, float grain, uint64_t seed) {
  x0 = std::max(0, x0);
  y0 = std::max(0, y0);
  x1 = std::min(img.cols, x1);
  y1 = std::min(img.rows, y1);
  for (int y = y0; y < y1; ++y) {
    Rgb* row = img.ptr<Rgb>(y);
    for (int x = x0; x < x1; ++x) row[x] = Scale(color, 1.0f + grain * TexelNoise(x, y, seed));
  }
}

// Multiplies every texel by (1 - strength * (fbm - 0.5) * 2): large-scale stains and weathering.
void Weather(cv::Mat& img, int cells, float strength, uint64_t seed) {
  for (int y = 0; y < img.rows; ++y) {
    Rgb* row = img.ptr<Rgb>(y);
    for (int x = 0; x < img.cols; ++x) {
      const float n = PeriodicFbm((x + 0.5f) / img.cols, (y + 0.5f) / img.rows, cells, cells, 4, seed);
      row[x] = Scale(row[x], 1.0f + strength * (n - 0.5f) * 2.0f);
    }
  }
}

void ClampImage(cv::Mat& img);

// A width x height texture whose texel (x, y) is texel(x, y), clamped to [0, 1].
template <typename Texel>
cv::Mat FillTexture(int width, int height, Texel&& texel) {
  cv::Mat img(height, width, CV_32FC3);
  for (int y = 0; y < height; ++y) {
    Rgb* row = img.ptr<Rgb>(y);
    for (int x = 0; x < width; ++x) row[x] = texel(x, y);
  }
  ClampImage(img);
  return img;
}

void ClampImage(cv::Mat& img) {
  for (int y = 0; y < img.rows; ++y) {
    Rgb* row = img.ptr<Rgb>(y);
    for (int x = 0; x < img.cols; ++x) {
      for (int c = 0; c < 3; ++c) row[x][c] = Clamp01(row[x][c]);
    }
  }
}

// A letter-like glyph: a 3x5 grid of random cells (at least a stem), drawn in `color`.
void DrawGlyph(cv::Mat& img, int x0, int y0, int cell, const Rgb& color, SimRandom& rng) {
  bool cells[5][3] = {};
  const int stem = rng.Int(0, 2);
  for (int r = 0; r < 5; ++r) cells[r][stem] = true;
  for (int r = 0; r < 5; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (rng.Chance(0.4)) cells[r][c] = true;
    }
  }
  for (int r = 0; r < 5; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (cells[r][c]) FillRect(img, x0 + c * cell, y0 + r * cell, x0 + (c + 1) * cell, y0 + (r + 1) * cell, color, 0.05f, 7);
    }
  }
}

// A window with frame, glass, mullions, sill and optional shutters / curtains / blinds, in pixel units.
void DrawWindow(cv::Mat& img, int x0, int y0, int w, int h, double ppm, const Rgb& frame, bool shutters,
                SimRandom& rng, uint64_t seed) {
  const int f = std::max(2, static_cast<int>(0.08 * ppm));
  // Deep reveal shadow around the opening.
  FillRect(img, x0 - f, y0 - f, x0 + w + f, y0 + h + f, Rgb(0.12f, 0.11f, 0.10f), 0.1f, seed + 1);
  FillRect(img, x0, y0, x0 + w, y0 + h, frame, 0.08f, seed + 2);
  // Glass: sky reflection gradient, darker below, with noise.
  const Rgb sky(0.35f, 0.42f, 0.52f);
  const Rgb dark(0.06f, 0.07f, 0.09f);
  const float reflect = static_cast<float>(rng.Uniform(0.2, 0.9));
  for (int y = y0 + f; y < y0 + h - f; ++y) {
    if (y < 0 || y >= img.rows) continue;
    Rgb* row = img.ptr<Rgb>(y);
    const float t = static_cast<float>(y - y0) / h;
    for (int x = x0 + f; x < x0 + w - f; ++x) {
      if (x < 0 || x >= img.cols) continue;
      const float diag = 0.5f + 0.5f * std::sin(0.05f * (x + 0.6f * y) + reflect * 6.0f);
      row[x] = Mix(sky, dark, Clamp01(t * 0.9f + 0.3f * diag - 0.2f * reflect + 0.2f)) *
               (1.0f + 0.06f * TexelNoise(x, y, seed + 3));
    }
  }
  const int kind = rng.Int(0, 3);
  if (kind == 1) {  // curtains: light cloth on both sides
    const Rgb cloth = Rgb(static_cast<float>(rng.Uniform(0.6, 0.9)), static_cast<float>(rng.Uniform(0.55, 0.85)),
                          static_cast<float>(rng.Uniform(0.5, 0.8)));
    FillRect(img, x0 + f, y0 + f, x0 + w / 3, y0 + h - f, cloth, 0.15f, seed + 4);
    FillRect(img, x0 + w - w / 3, y0 + f, x0 + w - f, y0 + h - f, cloth, 0.15f, seed + 5);
  } else if (kind == 2) {  // blinds half down: horizontal slats
    const int bottom = y0 + static_cast<int>(h * rng.Uniform(0.3, 0.7));
    for (int y = y0 + f; y < bottom; y += 3) FillRect(img, x0 + f, y, x0 + w - f, y + 2, Rgb(0.75f, 0.73f, 0.68f), 0.05f, seed + 6);
  }
  // Mullion and transom.
  FillRect(img, x0 + w / 2 - f / 2, y0, x0 + w / 2 + (f + 1) / 2, y0 + h, frame, 0.05f, seed + 7);
  const int transom = y0 + h / 3;
  FillRect(img, x0, transom - f / 2, x0 + w, transom + (f + 1) / 2, frame, 0.05f, seed + 8);
  // Sill with a shadow below.
  const int sill = std::max(2, static_cast<int>(0.07 * ppm));
  FillRect(img, x0 - 2 * f, y0 + h, x0 + w + 2 * f, y0 + h + sill, Rgb(0.78f, 0.76f, 0.72f), 0.08f, seed + 9);
  FillRect(img, x0 - 2 * f, y0 + h + sill, x0 + w + 2 * f, y0 + h + 2 * sill, Rgb(0.15f, 0.14f, 0.13f), 0.1f, seed + 10);
  if (shutters) {
    const Rgb color = rng.Chance(0.5) ? Rgb(0.18f, 0.35f, 0.2f) : Rgb(0.45f, 0.28f, 0.15f);
    const int sw = w / 2;
    for (int side = 0; side < 2; ++side) {
      const int sx = side == 0 ? x0 - f - sw : x0 + w + f;
      FillRect(img, sx, y0, sx + sw, y0 + h, color, 0.1f, seed + 11 + side);
      for (int y = y0 + 2; y < y0 + h - 2; y += 4) FillRect(img, sx + 2, y, sx + sw - 2, y + 1, Scale(color, 0.6f), 0.05f, seed);
    }
  }
}

}  // namespace

double HashToUnit(uint64_t h) { return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0); }

double SimRandom::Normal() {
  const double u1 = std::max(Uniform(), 1e-300);
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

namespace {

// The lattice of one periodic noise (period_x x period_y hashed values), cached per thread: texture generation
// evaluates the same few lattices millions of times.
const std::vector<float>& Lattice(int period_x, int period_y, uint64_t seed) {
  struct Entry {
    int px = 0, py = 0;
    uint64_t seed = 0;
    std::vector<float> values;
  };
  thread_local std::vector<Entry> cache;
  for (const Entry& e : cache) {
    if (e.px == period_x && e.py == period_y && e.seed == seed) return e.values;
  }
  if (cache.size() >= 16) cache.erase(cache.begin());
  Entry e;
  e.px = period_x;
  e.py = period_y;
  e.seed = seed;
  e.values.resize(static_cast<size_t>(period_x) * period_y);
  for (int iy = 0; iy < period_y; ++iy) {
    for (int ix = 0; ix < period_x; ++ix) {
      e.values[static_cast<size_t>(iy) * period_x + ix] =
          static_cast<float>(HashToUnit(HashCombine(seed, static_cast<uint64_t>(iy) * 1000003ULL + ix)));
    }
  }
  cache.push_back(std::move(e));
  return cache.back().values;
}

}  // namespace

float PeriodicValueNoise(float x, float y, int period_x, int period_y, uint64_t seed) {
  const std::vector<float>& lattice = Lattice(period_x, period_y, seed);
  const float fx = std::floor(x);
  const float fy = std::floor(y);
  const float tx = x - fx;
  const float ty = y - fy;
  const float sx = tx * tx * (3.0f - 2.0f * tx);  // smoothstep interpolation
  const float sy = ty * ty * (3.0f - 2.0f * ty);
  long ix = static_cast<long>(fx) % period_x, iy = static_cast<long>(fy) % period_y;
  if (ix < 0) ix += period_x;
  if (iy < 0) iy += period_y;
  const long ix1 = ix + 1 == period_x ? 0 : ix + 1, iy1 = iy + 1 == period_y ? 0 : iy + 1;
  const float a = lattice[iy * period_x + ix], b = lattice[iy * period_x + ix1];
  const float c = lattice[iy1 * period_x + ix], d = lattice[iy1 * period_x + ix1];
  return (a * (1 - sx) + b * sx) * (1 - sy) + (c * (1 - sx) + d * sx) * sy;
}

float PeriodicFbm(float u, float v, int cells_x, int cells_y, int octaves, uint64_t seed) {
  float sum = 0.0f, amplitude = 0.5f, norm = 0.0f;
  for (int o = 0; o < octaves; ++o) {
    const int px = cells_x << o, py = cells_y << o;
    sum += amplitude * PeriodicValueNoise(u * px, v * py, px, py, seed + o * 7919);
    norm += amplitude;
    amplitude *= 0.5f;
  }
  return sum / norm;
}

cv::Mat MakeFacadeTexture(int style, uint64_t seed) {
  constexpr int kWidth = 512, kHeight = 384;  // 12 m x 9 m
  const double ppm = kWidth / 12.0;
  SimRandom rng(HashCombine(seed, 0xfacade));
  cv::Mat img(kHeight, kWidth, CV_32FC3);
  const bool brick = style % 2 == 0;
  if (brick) {
    const Rgb base = style == 0 ? Rgb(0.55f, 0.25f, 0.17f) : Rgb(0.62f, 0.5f, 0.32f);
    const Rgb tint(static_cast<float>(rng.Uniform(0.85, 1.15)), static_cast<float>(rng.Uniform(0.9, 1.1)), 1.0f);
    const Rgb mortar(0.68f, 0.66f, 0.62f);
    const int bw = 12, bh = 4;  // 0.28 m x 0.094 m per brick incl. mortar (tiles 512 and 384 exactly)
    for (int y = 0; y < kHeight; ++y) {
      Rgb* row = img.ptr<Rgb>(y);
      const int course = y / bh;
      const int offset = (course % 2) * (bw / 2);
      for (int x = 0; x < kWidth; ++x) {
        const int bx = (x + offset) / bw;
        const bool joint = (y % bh == bh - 1) || ((x + offset) % bw == bw - 1);
        if (joint) {
          row[x] = Scale(mortar, 1.0f + 0.1f * TexelNoise(x, y, seed));
        } else {
          const float brick_shade =
              0.75f + 0.5f * static_cast<float>(HashToUnit(HashCombine(seed, course * 4096 + (bx % (kWidth / bw + 1)))));
          const Rgb c(base[0] * tint[0], base[1] * tint[1], base[2] * tint[2]);
          row[x] = Scale(c, brick_shade * (1.0f + 0.15f * TexelNoise(x, y, seed + 1)));
        }
      }
    }
  } else {
    const Rgb palette[] = {{0.85f, 0.8f, 0.68f}, {0.75f, 0.78f, 0.8f}, {0.86f, 0.7f, 0.55f},
                           {0.7f, 0.75f, 0.62f}, {0.9f, 0.88f, 0.84f}, {0.8f, 0.62f, 0.6f}};
    const Rgb base = palette[rng.Int(0, 5)];
    FillRect(img, 0, 0, kWidth, kHeight, base, 0.12f, seed + 2);
  }
  Weather(img, 4, brick ? 0.15f : 0.3f, seed + 3);
  const Rgb frame = rng.Chance(0.6) ? Rgb(0.88f, 0.88f, 0.85f) : Rgb(0.25f, 0.18f, 0.12f);
  const bool shutters = style >= 2 && rng.Chance(0.7);
  const int floor_px = kHeight / 3, bay_px = kWidth / 4;
  for (int floor = 0; floor < 3; ++floor) {
    const int fy = floor * floor_px;
    // Cornice band at the top of each floor with a shadow line.
    const Rgb band = brick ? Rgb(0.7f, 0.68f, 0.62f) : Scale(img.at<Rgb>(fy + 20, 5), 0.85f);
    FillRect(img, 0, fy, kWidth, fy + static_cast<int>(0.18 * ppm), band, 0.08f, seed + 20 + floor);
    FillRect(img, 0, fy + static_cast<int>(0.18 * ppm), kWidth, fy + static_cast<int>(0.25 * ppm),
             Rgb(0.2f, 0.19f, 0.18f), 0.1f, seed + 30 + floor);
    for (int bay = 0; bay < 4; ++bay) {
      const double width_m = rng.Uniform(1.1, 1.5);
      const double height_m = rng.Uniform(1.5, 1.9);
      const int w = static_cast<int>(width_m * ppm);
      const int h = static_cast<int>(height_m * ppm);
      const int x0 = bay * bay_px + (bay_px - w) / 2;
      const int y0 = fy + floor_px - static_cast<int>((0.9 + height_m) * ppm);
      DrawWindow(img, x0, y0, w, h, ppm, frame, shutters, rng, HashCombine(seed, floor * 10 + bay));
      if (rng.Chance(0.2)) {  // a balcony railing with bars
        const int ry = fy + floor_px - static_cast<int>(1.0 * ppm);
        const Rgb iron(0.12f, 0.12f, 0.13f);
        FillRect(img, x0 - 10, ry, x0 + w + 10, ry + 3, iron, 0.05f, seed);
        FillRect(img, x0 - 10, fy + floor_px - 6, x0 + w + 10, fy + floor_px - 2, Rgb(0.6f, 0.6f, 0.58f), 0.05f, seed);
        for (int x = x0 - 10; x < x0 + w + 10; x += 6) FillRect(img, x, ry, x + 2, fy + floor_px - 6, iron, 0.05f, seed);
      }
    }
  }
  // Drain pipe at one side.
  const int px = rng.Int(2, 8);
  FillRect(img, px, 0, px + 5, kHeight, Rgb(0.4f, 0.42f, 0.42f), 0.1f, seed + 40);
  for (int y = 20; y < kHeight; y += 64) FillRect(img, px - 2, y, px + 7, y + 3, Rgb(0.25f, 0.25f, 0.25f), 0.1f, seed);
  ClampImage(img);
  return img;
}

cv::Mat MakeShopfrontTexture(uint64_t seed) {
  constexpr int kWidth = 512, kHeight = 171;  // 12 m x 4 m
  const double ppm = kWidth / 12.0;
  SimRandom rng(HashCombine(seed, 0x5409));
  cv::Mat img(kHeight, kWidth, CV_32FC3);
  const Rgb stone(0.6f, 0.58f, 0.54f);
  FillRect(img, 0, 0, kWidth, kHeight, stone, 0.12f, seed);
  Weather(img, 6, 0.2f, seed + 1);
  // Stone block joints.
  for (int y = 0; y < kHeight; y += 21) FillRect(img, 0, y, kWidth, y + 1, Rgb(0.35f, 0.34f, 0.32f), 0.1f, seed);
  const int ground = kHeight;  // bottom row = street level
  for (int shop = 0; shop < 2; ++shop) {
    const int sx = shop * kWidth / 2;
    const Rgb sign_colors[] = {{0.7f, 0.1f, 0.1f}, {0.1f, 0.2f, 0.5f}, {0.1f, 0.4f, 0.2f},
                               {0.9f, 0.75f, 0.2f}, {0.15f, 0.15f, 0.15f}, {0.9f, 0.9f, 0.88f}};
    const Rgb sign = sign_colors[rng.Int(0, 5)];
    const Rgb letters = (sign[0] + sign[1] + sign[2]) > 1.5f ? Rgb(0.1f, 0.1f, 0.1f) : Rgb(0.95f, 0.95f, 0.9f);
    // Sign band 2.9..3.6 m.
    const int sy0 = ground - static_cast<int>(3.65 * ppm), sy1 = ground - static_cast<int>(2.95 * ppm);
    const int sign_x0 = sx + static_cast<int>(rng.Uniform(0.2, 0.8) * ppm);
    const int sign_x1 = sx + kWidth / 2 - static_cast<int>(rng.Uniform(0.2, 0.8) * ppm);
    FillRect(img, sign_x0 - 2, sy0 - 2, sign_x1 + 2, sy1 + 2, Rgb(0.1f, 0.1f, 0.1f), 0.05f, seed);
    FillRect(img, sign_x0, sy0, sign_x1, sy1, sign, 0.06f, seed + 2 + shop);
    const int cell = 3;
    const int n_letters = rng.Int(4, 9);
    const int text_w = n_letters * 4 * cell;
    int lx = (sign_x0 + sign_x1) / 2 - text_w / 2;
    const int ly = (sy0 + sy1) / 2 - 5 * cell / 2;
    for (int i = 0; i < n_letters; ++i, lx += 4 * cell) DrawGlyph(img, lx, ly, cell, letters, rng);
    // Display window and door.
    const bool door_left = rng.Chance(0.5);
    const int door_w = static_cast<int>(1.1 * ppm), door_h = static_cast<int>(2.3 * ppm);
    const int door_x = door_left ? sx + static_cast<int>(0.6 * ppm) : sx + kWidth / 2 - static_cast<int>(0.6 * ppm) - door_w;
    const Rgb door_color = rng.Chance(0.5) ? Rgb(0.3f, 0.18f, 0.1f) : Rgb(0.15f, 0.2f, 0.3f);
    FillRect(img, door_x - 3, ground - door_h - 3, door_x + door_w + 3, ground, Rgb(0.1f, 0.1f, 0.1f), 0.05f, seed);
    FillRect(img, door_x, ground - door_h, door_x + door_w, ground, door_color, 0.1f, seed + 5);
    for (int p = 0; p < 2; ++p) {  // door panels
      const int py0 = ground - door_h + 6 + p * door_h / 2, py1 = py0 + door_h / 2 - 12;
      FillRect(img, door_x + 6, py0, door_x + door_w - 6, py1, Scale(door_color, p == 0 ? 0.5f : 1.3f), 0.1f, seed + 6);
    }
    FillRect(img, door_x + door_w - 10, ground - door_h / 2, door_x + door_w - 6, ground - door_h / 2 + 8,
             Rgb(0.8f, 0.7f, 0.3f), 0.05f, seed);
    const int wx0 = door_left ? door_x + door_w + static_cast<int>(0.5 * ppm) : sx + static_cast<int>(0.5 * ppm);
    const int wx1 = door_left ? sx + kWidth / 2 - static_cast<int>(0.5 * ppm) : door_x - static_cast<int>(0.5 * ppm);
    DrawWindow(img, wx0, ground - static_cast<int>(2.6 * ppm), wx1 - wx0, static_cast<int>(2.0 * ppm), ppm,
               Rgb(0.2f, 0.2f, 0.22f), false, rng, HashCombine(seed, 100 + shop));
    // Goods in the window: a few coloured boxes.
    for (int g = 0; g < 5; ++g) {
      const int gx = rng.Int(wx0 + 4, std::max(wx0 + 5, wx1 - 20));
      const int gh = rng.Int(8, 25);
      const Rgb gc(static_cast<float>(rng.Uniform(0.1, 0.9)), static_cast<float>(rng.Uniform(0.1, 0.9)),
                   static_cast<float>(rng.Uniform(0.1, 0.9)));
      FillRect(img, gx, ground - static_cast<int>(0.65 * ppm) - gh, gx + rng.Int(6, 16), ground - static_cast<int>(0.65 * ppm), gc, 0.1f, seed);
    }
  }
  ClampImage(img);
  return img;
}

cv::Mat MakeAsphaltTexture(uint64_t seed) {
  constexpr int kSize = 512;  // 8 m
  cv::Mat img(kSize, kSize, CV_32FC3);
  for (int y = 0; y < kSize; ++y) {
    Rgb* row = img.ptr<Rgb>(y);
    for (int x = 0; x < kSize; ++x) {
      const float u = (x + 0.5f) / kSize, v = (y + 0.5f) / kSize;
      const float patches = PeriodicFbm(u, v, 3, 3, 3, seed);
      const float grain = PeriodicFbm(u, v, 64, 64, 2, seed + 1);
      const float g = 0.2f + 0.12f * (patches - 0.5f) + 0.1f * (grain - 0.5f) + 0.08f * TexelNoise(x, y, seed + 2);
      row[x] = Rgb(g, g, g * 1.04f);
    }
  }
  SimRandom rng(HashCombine(seed, 0xa5fa));
  for (int c = 0; c < 10; ++c) {  // cracks: random walks
    double x = rng.Uniform(0, kSize), y = rng.Uniform(0, kSize), angle = rng.Uniform(0, 2 * M_PI);
    for (int s = 0; s < 80; ++s) {
      angle += rng.Uniform(-0.5, 0.5);
      const double nx = x + 2.0 * std::cos(angle), ny = y + 2.0 * std::sin(angle);
      cv::line(img, cv::Point(static_cast<int>(x) % kSize, static_cast<int>(y) % kSize),
               cv::Point(static_cast<int>(nx) % kSize, static_cast<int>(ny) % kSize), cv::Scalar(0.07, 0.07, 0.07), 1);
      x = std::fmod(nx + kSize, kSize);
      y = std::fmod(ny + kSize, kSize);
    }
  }
  for (int p = 0; p < 3; ++p) {  // repaired patches
    const int px = rng.Int(0, kSize - 100), py = rng.Int(0, kSize - 100);
    const int pw = rng.Int(30, 90), ph = rng.Int(30, 90);
    for (int y = py; y < py + ph; ++y) {
      for (int x = px; x < px + pw; ++x) img.at<Rgb>(y, x) = Scale(img.at<Rgb>(y, x), 0.7f);
    }
    cv::rectangle(img, cv::Rect(px, py, pw, ph), cv::Scalar(0.1, 0.1, 0.1), 1);
  }
  ClampImage(img);
  return img;
}

cv::Mat MakeSidewalkTexture(uint64_t seed) {
  constexpr int kSize = 256;  // 4 m, slabs of 0.5 m = 32 px
  return FillTexture(kSize, kSize, [&](int x, int y) {
    const int sx = x / 32, sy = y / 32;
    const bool joint = x % 32 == 0 || y % 32 == 0;
    const float slab = 0.5f + 0.12f * static_cast<float>(HashToUnit(HashCombine(seed, sy * 64 + sx)));
    const float stain = PeriodicFbm((x + 0.5f) / kSize, (y + 0.5f) / kSize, 4, 4, 3, seed + 1);
    float g = joint ? 0.28f : slab * (0.85f + 0.3f * stain) + 0.06f * TexelNoise(x, y, seed + 2);
    return Rgb(g * 1.02f, g, g * 0.95f);
  });
}

cv::Mat MakeGrassTexture(uint64_t seed) {
  constexpr int kSize = 256;
  return FillTexture(kSize, kSize, [&](int x, int y) {
    const float u = (x + 0.5f) / kSize, v = (y + 0.5f) / kSize;
    const float clumps = PeriodicFbm(u, v, 8, 8, 4, seed);
    const float blade = TexelNoise(x, y, seed + 1);
    const float g = 0.6f + 0.5f * (clumps - 0.5f) + 0.35f * blade;
    return Rgb(0.16f * g, 0.36f * g, 0.1f * g);
  });
}

cv::Mat MakeFoliageTexture(uint64_t seed) {
  constexpr int kSize = 256;
  return FillTexture(kSize, kSize, [&](int x, int y) {
    const float u = (x + 0.5f) / kSize, v = (y + 0.5f) / kSize;
    const float clusters = PeriodicFbm(u, v, 6, 6, 4, seed);
    const float leaves = PeriodicValueNoise(u * 48, v * 48, 48, 48, seed + 1);
    const float lit = clusters > 0.48f ? 1.0f : 0.35f;
    const float g = lit * (0.6f + 0.6f * (leaves - 0.5f)) + 0.15f * TexelNoise(x, y, seed + 2);
    return Rgb(0.14f * g, 0.32f * g, 0.09f * g);
  });
}

cv::Mat MakeBarkTexture(uint64_t seed) {
  constexpr int kWidth = 64, kHeight = 128;
  return FillTexture(kWidth, kHeight, [&](int x, int y) {
    const float furrow = PeriodicFbm((x + 0.5f) / kWidth, (y + 0.5f) / kHeight, 8, 2, 3, seed);
    const float g = 0.55f + 0.8f * (furrow - 0.5f) + 0.15f * TexelNoise(x, y, seed + 1);
    return Rgb(0.33f * g, 0.24f * g, 0.16f * g);
  });
}

cv::Mat MakeRoofTexture(uint64_t seed) {
  constexpr int kSize = 128;
  return FillTexture(kSize, kSize, [&](int x, int y) {
    const float g = 0.35f + 0.2f * TexelNoise(x, y, seed) +
                      0.1f * (PeriodicFbm((x + 0.5f) / kSize, (y + 0.5f) / kSize, 4, 4, 3, seed + 1) - 0.5f);
    return Rgb(g, g * 0.97f, g * 0.93f);
  });
}

cv::Mat MakePaintTexture(uint64_t seed) {
  constexpr int kSize = 64;
  return FillTexture(kSize, kSize, [&](int x, int y) {
    const float g = 0.8f + 0.05f * TexelNoise(x, y, seed) +
                      0.1f * (PeriodicFbm((x + 0.5f) / kSize, (y + 0.5f) / kSize, 3, 3, 3, seed + 1) - 0.5f);
    return Rgb(g, g, g);
  });
}

cv::Mat MakeGlassTexture(uint64_t seed) {
  constexpr int kWidth = 64, kHeight = 32;
  return FillTexture(kWidth, kHeight, [&](int x, int y) {
    const float t = static_cast<float>(y) / kHeight;
    const float streak = 0.5f + 0.5f * std::sin(0.3f * (x + y));
    const float g = 0.08f + 0.2f * (1.0f - t) * streak + 0.02f * TexelNoise(x, y, seed);
    return Rgb(g * 0.9f, g, g * 1.15f);
  });
}

cv::Mat MakeClothTexture(uint64_t seed) {
  constexpr int kWidth = 32, kHeight = 64;
  SimRandom rng(seed);
  const Rgb a(static_cast<float>(rng.Uniform(0.05, 0.8)), static_cast<float>(rng.Uniform(0.05, 0.8)),
              static_cast<float>(rng.Uniform(0.05, 0.8)));
  const Rgb b = Scale(a, static_cast<float>(rng.Uniform(0.3, 0.7)));
  const int stripe = rng.Int(3, 8);
  const bool checks = rng.Chance(0.5);
  return FillTexture(kWidth, kHeight, [&](int x, int y) {
    const bool on = checks ? (((x / stripe) + (y / stripe)) % 2 == 0) : ((y / stripe) % 2 == 0);
    return Scale(on ? a : b, 1.0f + 0.1f * TexelNoise(x, y, seed));
  });
}

}  // namespace retrace
