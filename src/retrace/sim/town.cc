#include "retrace/sim/town.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <set>
#include <tuple>

#include <opencv2/imgcodecs.hpp>

#include "retrace/sim/procedural_texture.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

struct Materials {
  std::vector<int> facades;      // upper floors
  std::vector<int> shopfronts;   // ground floors facing the street
  int asphalt, sidewalk, grass, foliage, bark, roof, marking, curb, glass, tire, metal, headlight, taillight;
  int sign_red, sign_blue, sign_white, skin, dark_cloth;
  std::vector<int> paints;       // car colours
  std::vector<int> cloths;       // pedestrians
  std::vector<float> facade_tile_v;  // tile height (m) of each facade texture (width is 12 m)
};

Materials MakeMaterials(const TownOptions& options, Scene* scene) {
  const uint64_t seed = options.seed;
  Materials m;
  auto textured = [&](const cv::Mat& image, const Vector3f& tint = Vector3f(1, 1, 1)) {
    Material material;
    material.texture = scene->AddTexture(Texture(image));
    material.color = tint;
    return scene->AddMaterial(material);
  };
  auto uniform = [&](const Vector3f& color, bool emissive = false) {
    Material material;
    material.color = color;
    material.emissive = emissive;
    return scene->AddMaterial(material);
  };
  if (!options.photo_folder.empty()) {
    namespace fs = std::filesystem;
    std::error_code error;
    CheckInput(fs::is_directory(options.photo_folder, error), options.photo_folder, "photo folder not found");
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(options.photo_folder)) {
      std::string ext = entry.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".jpg" || ext == ".jpeg" || ext == ".png") files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    for (const auto& file : files) {
      const cv::Mat image = cv::imread(file.string(), cv::IMREAD_COLOR);
      CheckInput(!image.empty(), file.string(), "cannot read the image");
      m.facades.push_back(textured(image));
      m.facade_tile_v.push_back(12.0f * image.rows / image.cols);
    }
    CheckInput(!m.facades.empty(), options.photo_folder, "no .jpg or .png photos in the photo folder");
  } else {
    for (int variant = 0; variant < 8; ++variant) {
      m.facades.push_back(textured(MakeFacadeTexture(variant % 4, HashCombine(seed, 100 + variant))));
      m.facade_tile_v.push_back(9.0f);
    }
  }
  for (int variant = 0; variant < 4; ++variant) {
    m.shopfronts.push_back(textured(MakeShopfrontTexture(HashCombine(seed, 200 + variant))));
  }
  m.asphalt = textured(MakeAsphaltTexture(HashCombine(seed, 1)));
  m.sidewalk = textured(MakeSidewalkTexture(HashCombine(seed, 2)));
  m.grass = textured(MakeGrassTexture(HashCombine(seed, 3)));
  m.foliage = textured(MakeFoliageTexture(HashCombine(seed, 4)));
  m.bark = textured(MakeBarkTexture(HashCombine(seed, 5)));
  m.roof = textured(MakeRoofTexture(HashCombine(seed, 6)));
  m.marking = uniform(Vector3f(0.85f, 0.85f, 0.82f));
  m.curb = textured(MakeSidewalkTexture(HashCombine(seed, 7)), Vector3f(0.9f, 0.9f, 0.9f));
  m.glass = textured(MakeGlassTexture(HashCombine(seed, 8)));
  m.tire = uniform(Vector3f(0.05f, 0.05f, 0.05f));
  m.metal = uniform(Vector3f(0.3f, 0.32f, 0.33f));
  m.headlight = uniform(Vector3f(0.9f, 0.9f, 0.8f));
  m.taillight = uniform(Vector3f(0.7f, 0.05f, 0.05f));
  m.sign_red = uniform(Vector3f(0.75f, 0.08f, 0.08f));
  m.sign_blue = uniform(Vector3f(0.1f, 0.25f, 0.7f));
  m.sign_white = uniform(Vector3f(0.9f, 0.9f, 0.9f));
  m.skin = uniform(Vector3f(0.75f, 0.55f, 0.45f));
  m.dark_cloth = uniform(Vector3f(0.1f, 0.1f, 0.15f));
  const cv::Mat paint = MakePaintTexture(HashCombine(seed, 9));
  const Vector3f colors[] = {{0.8f, 0.1f, 0.1f},  {0.1f, 0.2f, 0.6f},  {0.9f, 0.9f, 0.9f}, {0.1f, 0.1f, 0.1f},
                             {0.5f, 0.5f, 0.52f}, {0.1f, 0.45f, 0.2f}, {0.9f, 0.7f, 0.1f}, {0.4f, 0.2f, 0.1f}};
  const int paint_texture = scene->AddTexture(Texture(paint));
  for (const auto& c : colors) {
    Material material;
    material.texture = paint_texture;
    material.color = c;
    m.paints.push_back(scene->AddMaterial(material));
  }
  for (int i = 0; i < 6; ++i) m.cloths.push_back(textured(MakeClothTexture(HashCombine(seed, 300 + i))));
  // Cloud cover for the sky.
  cv::Mat clouds(256, 256, CV_32FC3);
  for (int y = 0; y < clouds.rows; ++y) {
    for (int x = 0; x < clouds.cols; ++x) {
      const float c = PeriodicFbm((x + 0.5f) / 256, (y + 0.5f) / 256, 4, 4, 5, HashCombine(seed, 10));
      clouds.at<cv::Vec3f>(y, x) = cv::Vec3f(c, c, c);
    }
  }
  scene->set_clouds(Texture(clouds));
  return m;
}

// A car model in its own frame: x forward (length 4.3 m), y left, z up, origin at the ground centre.
Mesh MakeCar(const Materials& m, int paint) {
  Mesh car;
  car.AddBox(Vector3f(-2.15f, -0.87f, 0.32f), Vector3f(2.15f, 0.87f, 0.95f), 2.0f, paint);
  car.AddBox(Vector3f(-1.2f, -0.8f, 0.95f), Vector3f(0.9f, 0.8f, 1.4f), 1.0f, m.glass);
  car.AddBox(Vector3f(-1.15f, -0.75f, 1.4f), Vector3f(0.85f, 0.75f, 1.47f), 2.0f, paint);
  for (float x : {-1.35f, 1.35f}) {
    for (float y : {-0.8f, 0.8f}) {
      car.AddBox(Vector3f(x - 0.33f, y - 0.12f, 0.0f), Vector3f(x + 0.33f, y + 0.12f, 0.66f), 1.0f, m.tire);
    }
  }
  for (float y : {-0.6f, 0.6f}) {
    car.AddBox(Vector3f(2.14f, y - 0.18f, 0.7f), Vector3f(2.17f, y + 0.18f, 0.85f), 1.0f, m.headlight);
    car.AddBox(Vector3f(-2.17f, y - 0.18f, 0.7f), Vector3f(-2.14f, y + 0.18f, 0.85f), 1.0f, m.taillight);
  }
  car.AddBox(Vector3f(-2.2f, -0.5f, 0.35f), Vector3f(-2.15f, 0.5f, 0.5f), 1.0f, m.metal);  // bumper
  car.AddBox(Vector3f(2.15f, -0.5f, 0.35f), Vector3f(2.2f, 0.5f, 0.5f), 1.0f, m.metal);
  return car;
}

// A pedestrian in its own frame (x forward, z up), standing on z = `base`: legs of `trousers`, body and arms of
// `cloth`, a head of `skin` (material indices).
Mesh MakePedestrian(int cloth, int trousers, int skin, float base, float height, uint64_t seed) {
  Mesh p;
  const float s = height / 1.75f;
  p.AddBox(Vector3f(-0.1f, -0.2f, base), Vector3f(0.1f, -0.03f, base + 0.85f * s), 1.0f, trousers);
  p.AddBox(Vector3f(-0.1f, 0.03f, base), Vector3f(0.1f, 0.2f, base + 0.85f * s), 1.0f, trousers);
  p.AddBox(Vector3f(-0.14f, -0.24f, base + 0.85f * s), Vector3f(0.14f, 0.24f, base + 1.5f * s), 0.6f, cloth);
  p.AddBox(Vector3f(-0.06f, -0.3f, base + 0.9f * s), Vector3f(0.06f, -0.24f, base + 1.45f * s), 0.6f, cloth);
  p.AddBox(Vector3f(-0.06f, 0.24f, base + 0.9f * s), Vector3f(0.06f, 0.3f, base + 1.45f * s), 0.6f, cloth);
  p.AddBlob(Vector3f(0.0f, 0.0f, base + 1.63f * s), Vector3f(0.11f, 0.1f, 0.13f) * s, 1, 0.05f, seed, 0.3f, skin);
  return p;
}

void AddTree(Mesh& mesh, const Materials& m, const Vector3f& base, SimRandom& rng) {
  const float trunk_h = static_cast<float>(rng.Uniform(2.2, 3.5));
  const float radius = static_cast<float>(rng.Uniform(1.4, 2.4));
  mesh.AddCylinder(base, 0.16f, trunk_h + radius * 0.5f, 6, 1.0f, 2.0f, m.bark);
  mesh.AddBlob(base + Vector3f(0, 0, trunk_h + radius * 0.8f), Vector3f(radius, radius, radius * 1.1f), 2, 0.15f,
               rng.Next(), 3.0f, m.foliage);
}

void AddLamp(Mesh& mesh, const Materials& m, const Vector3f& base, const Vector2f& toward_road) {
  mesh.AddCylinder(base, 0.07f, 5.5f, 6, 1.0f, 1.0f, m.metal);
  const Vector3f arm_end = base + Vector3f(toward_road.x() * 1.2f, toward_road.y() * 1.2f, 5.5f);
  const Vector3f lo = base.cwiseMin(arm_end) + Vector3f(-0.05f, -0.05f, 5.4f - base.z() + base.z());
  const Vector3f hi = base.cwiseMax(arm_end) + Vector3f(0.05f, 0.05f, 0.0f);
  mesh.AddBox(Vector3f(lo.x(), lo.y(), base.z() + 5.4f), Vector3f(hi.x(), hi.y(), base.z() + 5.5f), 1.0f, m.metal);
  mesh.AddBox(arm_end + Vector3f(-0.25f, -0.15f, -0.2f), arm_end + Vector3f(0.25f, 0.15f, 0.0f), 1.0f,
              m.headlight);
}

void AddSign(Mesh& mesh, const Materials& m, const Vector3f& base, const Vector3f& facing, SimRandom& rng) {
  mesh.AddCylinder(base, 0.04f, 2.6f, 5, 1.0f, 1.0f, m.metal);
  const Vector3f centre = base + Vector3f(0, 0, 2.3f) + 0.06f * facing;
  if (rng.Chance(0.5)) {
    mesh.AddDisc(centre, facing, 0.35f, 16, m.sign_red);
    mesh.AddDisc(centre + 0.01f * facing, facing, 0.26f, 16, m.sign_white);
    mesh.AddBox(centre + Vector3f(-0.18f, -0.18f, -0.05f) + 0.02f * facing,
                centre + Vector3f(0.18f, 0.18f, 0.05f) + 0.02f * facing, 1.0f, m.sign_red);
  } else {
    const Vector3f side = Vector3f(0, 0, 1).cross(facing).normalized();
    const Vector3f up(0, 0, 1);
    mesh.AddQuad(centre - 0.3f * side + 0.3f * up, centre + 0.3f * side + 0.3f * up, centre + 0.3f * side - 0.3f * up,
                 centre - 0.3f * side - 0.3f * up, Vector2f(0, 0), Vector2f(1, 0), Vector2f(1, 1), Vector2f(0, 1),
                 m.sign_blue);
    const Vector3f c2 = centre + 0.01f * facing;
    mesh.AddQuad(c2 - 0.08f * side + 0.2f * up, c2 + 0.08f * side + 0.2f * up, c2 + 0.08f * side - 0.2f * up,
                 c2 - 0.08f * side - 0.2f * up, Vector2f(0, 0), Vector2f(1, 0), Vector2f(1, 1), Vector2f(0, 1),
                 m.sign_white);
  }
}

// A wall quad from (a, z0) to (b, z1) (a, b ground points, the wall facing right of a->b), textured with a 12 m
// wide texture of tile height tile_v whose top row is at z1 (floors line up with the roof line).
void AddWall(Mesh& mesh, const Vector2d& a, const Vector2d& b, double z0, double z1, float tile_v, int material,
             float u_offset) {
  const Vector3f p0(a.x(), a.y(), z1), p1(b.x(), b.y(), z1), p2(b.x(), b.y(), z0), p3(a.x(), a.y(), z0);
  mesh.AddTiledQuad(p0, p1, p2, p3, 12.0f, tile_v, material, Vector2f(u_offset, 0.0f));
}

struct Lot {
  double x0, y0, x1, y1;  // inside the sidewalks
};

void AddBuilding(Mesh& mesh, const Materials& m, const TownOptions& options, double x0, double y0, double x1,
                 double y1, int street_side, SimRandom& rng) {
  // street_side: 0 south, 1 east, 2 north, 3 west: which wall faces the street (gets the shop fronts).
  const double base = options.sidewalk_height;
  const int floors = rng.Int(options.min_upper_floors, options.max_upper_floors);
  const double top = base + 4.0 + 3.0 * floors;
  const size_t facade = rng.Int(0, static_cast<int>(m.facades.size()) - 1);
  const int facade_material = m.facades[facade];
  const float tile_v = m.facade_tile_v[facade];
  const int shop = m.shopfronts[rng.Int(0, static_cast<int>(m.shopfronts.size()) - 1)];
  const bool has_shops = rng.Chance(0.7);
  // Walls counter-clockwise seen from above: seen from outside each runs left to right, so texture u grows to the
  // right and signs are not mirrored.
  const Vector2d c[4] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  const float u_offset = static_cast<float>(rng.Uniform(0.0, 1.0));
  for (int side = 0; side < 4; ++side) {
    const Vector2d& a = c[side];
    const Vector2d& b = c[(side + 1) % 4];
    if (side == street_side && has_shops) {
      AddWall(mesh, a, b, base, base + 4.0, 4.0f, shop, u_offset);
      AddWall(mesh, a, b, base + 4.0, top, tile_v, facade_material, u_offset);
    } else {
      AddWall(mesh, a, b, base, top, tile_v, facade_material, u_offset);
    }
  }
  mesh.AddTiledQuad(Vector3f(x0, y0, top), Vector3f(x1, y0, top), Vector3f(x1, y1, top), Vector3f(x0, y1, top), 8.0f,
                    8.0f, m.roof);
  // Parapet: a slightly wider slab at the roof line (its shadow line and overhang give strong edges).
  mesh.AddBox(Vector3f(x0 - 0.2, y0 - 0.2, top), Vector3f(x1 + 0.2, y1 + 0.2, top + 0.5), 4.0f, m.curb);
}

// The streets' centre lines: the first draws of the town's random sequence.
TownLayout PlanStreets(const TownOptions& options, SimRandom* rng) {
  TownLayout layout;
  layout.road_width = options.road_width;
  layout.sidewalk_width = options.sidewalk_width;
  const double hw = options.road_width / 2.0 + options.sidewalk_width;  // street centre to lot edge
  layout.street_x.push_back(0.0);
  for (int i = 0; i < options.blocks_x; ++i) {
    layout.street_x.push_back(layout.street_x.back() + 2.0 * hw +
                              rng->Uniform(options.block_size_min, options.block_size_max));
  }
  layout.street_y.push_back(0.0);
  for (int j = 0; j < options.blocks_y; ++j) {
    layout.street_y.push_back(layout.street_y.back() + 2.0 * hw +
                              rng->Uniform(options.block_size_min, options.block_size_max));
  }
  return layout;
}

}  // namespace

TownLayout PlanTownLayout(const TownOptions& options) {
  SimRandom rng(options.seed);
  return PlanStreets(options, &rng);
}

TownLayout BuildTown(const TownOptions& options, Scene* scene) {
  SimRandom rng(options.seed);
  const Materials m = MakeMaterials(options, scene);
  TownLayout layout = PlanStreets(options, &rng);
  const double hw = options.road_width / 2.0 + options.sidewalk_width;  // street centre to lot edge
  const double ring = 18.0;
  const double min_x = -hw - ring, max_x = layout.street_x.back() + hw + ring;
  const double min_y = -hw - ring, max_y = layout.street_y.back() + hw + ring;

  Mesh ground, buildings, details;
  // Road surface over the town and grass beyond it.
  ground.AddTiledQuad(Vector3f(min_x - 10, max_y + 10, 0), Vector3f(max_x + 10, max_y + 10, 0),
                      Vector3f(max_x + 10, min_y - 10, 0), Vector3f(min_x - 10, min_y - 10, 0), 8.0f, 8.0f, m.asphalt);
  const double far = 3000.0;
  const Vector3f g[4] = {{float(min_x - 10), float(min_y - 10), 0}, {float(max_x + 10), float(min_y - 10), 0},
                         {float(max_x + 10), float(max_y + 10), 0}, {float(min_x - 10), float(max_y + 10), 0}};
  const Vector3f o[4] = {{float(min_x - far), float(min_y - far), 0}, {float(max_x + far), float(min_y - far), 0},
                         {float(max_x + far), float(max_y + far), 0}, {float(min_x - far), float(max_y + far), 0}};
  for (int k = 0; k < 4; ++k) {
    ground.AddTiledQuad(g[k], g[(k + 1) % 4], o[(k + 1) % 4], o[k], 4.0f, 4.0f, m.grass);
  }

  // Blocks: the inner grid plus a ring of buildings around the town.
  std::vector<std::pair<double, double>> xs, ys;  // lot extents
  xs.push_back({min_x, -hw});
  for (int i = 0; i + 1 < static_cast<int>(layout.street_x.size()); ++i) {
    xs.push_back({layout.street_x[i] + hw, layout.street_x[i + 1] - hw});
  }
  xs.push_back({layout.street_x.back() + hw, max_x});
  ys.push_back({min_y, -hw});
  for (int j = 0; j + 1 < static_cast<int>(layout.street_y.size()); ++j) {
    ys.push_back({layout.street_y[j] + hw, layout.street_y[j + 1] - hw});
  }
  ys.push_back({layout.street_y.back() + hw, max_y});
  const float hs = static_cast<float>(options.sidewalk_height);
  const double sw = options.sidewalk_width;
  for (size_t bi = 0; bi < xs.size(); ++bi) {
    for (size_t bj = 0; bj < ys.size(); ++bj) {
      const bool outer = bi == 0 || bj == 0 || bi + 1 == xs.size() || bj + 1 == ys.size();
      const Lot lot{xs[bi].first, ys[bj].first, xs[bi].second, ys[bj].second};
      // Sidewalk slab with curbs.
      const float sx0 = lot.x0 - sw, sy0 = lot.y0 - sw, sx1 = lot.x1 + sw, sy1 = lot.y1 + sw;
      ground.AddTiledQuad(Vector3f(sx0, sy0, hs), Vector3f(sx1, sy0, hs), Vector3f(sx1, sy1, hs),
                          Vector3f(sx0, sy1, hs), 4.0f, 4.0f, m.sidewalk);
      const Vector3f s[4] = {{sx0, sy0, 0}, {sx1, sy0, 0}, {sx1, sy1, 0}, {sx0, sy1, 0}};
      for (int k = 0; k < 4; ++k) {
        const Vector3f up(0, 0, hs);
        ground.AddTiledQuad(s[k] + up, s[(k + 1) % 4] + up, s[(k + 1) % 4], s[k], 1.0f, 1.0f, m.curb);
      }
      const bool park = !outer && rng.Chance(options.park_probability);
      if (park) {
        ground.AddTiledQuad(Vector3f(lot.x0, lot.y0, hs + 0.01f), Vector3f(lot.x1, lot.y0, hs + 0.01f),
                            Vector3f(lot.x1, lot.y1, hs + 0.01f), Vector3f(lot.x0, lot.y1, hs + 0.01f), 4.0f, 4.0f,
                            m.grass);
        const int trees = rng.Int(6, 14);
        for (int t = 0; t < trees; ++t) {
          AddTree(details, m, Vector3f(rng.Uniform(lot.x0 + 3, lot.x1 - 3), rng.Uniform(lot.y0 + 3, lot.y1 - 3), hs),
                  rng);
        }
        continue;
      }
      // Buildings: rows along the south and north edges span the full width, the west and east rows fit between.
      const double width = lot.x1 - lot.x0, height = lot.y1 - lot.y0;
      const double depth = std::min(rng.Uniform(9.0, 15.0), std::min(width, height) / 2.0 - 0.5);
      auto row = [&](double from, double to, const std::function<void(double, double)>& add) {
        double a = from;
        while (to - a > 1.0) {
          double b = a + rng.Uniform(8.0, 20.0);
          if (to - b < 6.0) b = to;
          add(a, b);
          a = b;
        }
      };
      row(lot.x0, lot.x1, [&](double a, double b) {
        AddBuilding(buildings, m, options, a, lot.y0, b, lot.y0 + depth, 0, rng);
        AddBuilding(buildings, m, options, a, lot.y1 - depth, b, lot.y1, 2, rng);
      });
      row(lot.y0 + depth, lot.y1 - depth, [&](double a, double b) {
        AddBuilding(buildings, m, options, lot.x0, a, lot.x0 + depth, b, 3, rng);
        AddBuilding(buildings, m, options, lot.x1 - depth, a, lot.x1, b, 1, rng);
      });
      if (outer) continue;
      // Street furniture along the four sidewalks: trees, lamps, signs near corners, parked cars on the road.
      const Vector2d corners[4] = {{lot.x0, lot.y0}, {lot.x1, lot.y0}, {lot.x1, lot.y1}, {lot.x0, lot.y1}};
      for (int side = 0; side < 4; ++side) {
        const Vector2d a = corners[side], b = corners[(side + 1) % 4];
        const Vector2d dir = (b - a).normalized();
        const Vector2d out(dir.y(), -dir.x());  // towards the street (lot is on the left of a->b)
        const double length = (b - a).norm();
        if (options.tree_spacing > 0.0) {
          for (double d = rng.Uniform(3.0, options.tree_spacing); d < length - 3.0;
               d += options.tree_spacing * rng.Uniform(0.7, 1.3)) {
            if (rng.Chance(0.3)) continue;
            const Vector2d p = a + d * dir + (sw - 0.8) * out;
            AddTree(details, m, Vector3f(p.x(), p.y(), hs), rng);
          }
        }
        for (double d = rng.Uniform(5.0, 15.0); d < length - 3.0; d += rng.Uniform(18.0, 30.0)) {
          const Vector2d p = a + d * dir + (sw - 0.3) * out;
          AddLamp(details, m, Vector3f(p.x(), p.y(), hs), out.cast<float>());
        }
        if (rng.Chance(0.6)) {
          const Vector2d p = a + 1.5 * dir + (sw - 0.4) * out;
          AddSign(details, m, Vector3f(p.x(), p.y(), hs), Vector3f(-dir.x(), -dir.y(), 0), rng);
        }
        // Parked cars along the curb, away from the junctions.
        for (double d = 9.0; d + 9.0 < length; d += 6.0) {
          if (!rng.Chance(options.parked_car_probability)) continue;
          const Vector2d p = a + d * dir + (sw + 1.1) * out;
          const double yaw = std::atan2(dir.y(), dir.x()) + (rng.Chance(0.5) ? 0.0 : M_PI) + rng.Uniform(-0.03, 0.03);
          Matrix3d r;
          r << std::cos(yaw), -std::sin(yaw), 0, std::sin(yaw), std::cos(yaw), 0, 0, 0, 1;
          details.Append(MakeCar(m, m.paints[rng.Int(0, static_cast<int>(m.paints.size()) - 1)]),
                         Rigid3d(r, Vector3d(p.x(), p.y(), 0.0)));
        }
      }
    }
  }
  // Road markings: dashed centre lines between junctions, crosswalks before each junction.
  const double rw = options.road_width;
  auto marking_rect = [&](const Vector2d& centre, const Vector2d& along, double length, double width) {
    const Vector2d side(-along.y(), along.x());
    const Vector2d p0 = centre - 0.5 * length * along - 0.5 * width * side;
    const Vector2d p1 = centre + 0.5 * length * along - 0.5 * width * side;
    const Vector2d p2 = centre + 0.5 * length * along + 0.5 * width * side;
    const Vector2d p3 = centre - 0.5 * length * along + 0.5 * width * side;
    ground.AddTiledQuad(Vector3f(p0.x(), p0.y(), 0.01f), Vector3f(p1.x(), p1.y(), 0.01f),
                        Vector3f(p2.x(), p2.y(), 0.01f), Vector3f(p3.x(), p3.y(), 0.01f), 1.0f, 1.0f, m.marking);
  };
  auto street_segment = [&](const Vector2d& a, const Vector2d& b) {
    const Vector2d dir = (b - a).normalized();
    const double length = (b - a).norm();
    for (double d = hw + 4.0; d + 3.0 < length - hw - 4.0; d += 9.0) marking_rect(a + (d + 1.5) * dir, dir, 3.0, 0.15);
    for (int end = 0; end < 2; ++end) {
      const Vector2d base = end == 0 ? Vector2d(a + (hw + 1.5) * dir) : Vector2d(b - (hw + 1.5) * dir);
      const Vector2d side(-dir.y(), dir.x());
      for (double s = -rw / 2 + 0.5; s < rw / 2 - 0.4; s += 1.0) marking_rect(base + s * side, dir, 3.0, 0.5);
    }
  };
  for (double x : layout.street_x) {
    for (size_t j = 0; j + 1 < layout.street_y.size(); ++j) {
      street_segment(Vector2d(x, layout.street_y[j]), Vector2d(x, layout.street_y[j + 1]));
    }
  }
  for (double y : layout.street_y) {
    for (size_t i = 0; i + 1 < layout.street_x.size(); ++i) {
      street_segment(Vector2d(layout.street_x[i], y), Vector2d(layout.street_x[i + 1], y));
    }
  }
  scene->AddStaticMesh(ground);
  scene->AddStaticMesh(buildings);
  scene->AddStaticMesh(details);

  // Moving occluders. Pedestrians walk around blocks on the sidewalks or back and forth across a street; cars
  // drive around blocks in the right lane.
  for (int k = 0; k < options.num_pedestrians; ++k) {
    const int i = rng.Int(0, options.blocks_x - 1), j = rng.Int(0, options.blocks_y - 1);
    ScriptedPath path;
    path.speed = rng.Uniform(1.0, 1.7);
    const Vector2d lo(layout.street_x[i] + hw - 1.2, layout.street_y[j] + hw - 1.2);
    const Vector2d hi(layout.street_x[i + 1] - hw + 1.2, layout.street_y[j + 1] - hw + 1.2);
    if (k % 3 == 2) {  // crossing the street at a crosswalk
      const Vector2d a(lo.x() + 0.5, lo.y()), b(lo.x() + 0.5, lo.y() - 2.0 * hw + 2.4);
      path.points = {a, b};
      path.loop = false;
      path.speed = rng.Uniform(0.8, 1.3);
    } else {
      path.points = {lo, Vector2d(hi.x(), lo.y()), hi, Vector2d(lo.x(), hi.y())};
      if (rng.Chance(0.5)) std::reverse(path.points.begin(), path.points.end());
    }
    path.start_offset = rng.Uniform(0.0, 200.0);
    scene->AddMovingObject(MakePedestrian(m.cloths[rng.Int(0, static_cast<int>(m.cloths.size()) - 1)], m.dark_cloth,
                                          m.skin, hs, static_cast<float>(rng.Uniform(1.55, 1.9)), rng.Next()),
                           path);
  }
  for (int k = 0; k < options.num_moving_cars; ++k) {
    const int i = rng.Int(0, options.blocks_x - 1), j = rng.Int(0, options.blocks_y - 1);
    const std::vector<Vector2d> loop = LoopRouteJunctions(layout, i, j, i + 1, j + 1);
    ScriptedPath path;
    path.points = OffsetPolyline(loop, layout.lane_offset());
    path.points.pop_back();  // the loop closes itself
    path.speed = rng.Uniform(4.0, 8.0);
    path.start_offset = rng.Uniform(0.0, 300.0);
    scene->AddMovingObject(MakeCar(m, m.paints[rng.Int(0, static_cast<int>(m.paints.size()) - 1)]), path);
  }
  scene->set_sky(SkyType::kProcedural);
  scene->Commit();
  return layout;
}

Vector2d EscortSpot(int k) {
  // Beside the camera first, then in front of it beside the line of sight, behind it, straight ahead and behind:
  // {bearing (degrees, counter-clockwise from ahead), distance (m)}.
  static constexpr double kSpots[kMaxEscorts][2] = {{90, 0.6},   {-90, 0.6},  {40, 0.75}, {-40, 0.75},
                                                    {140, 0.75}, {-140, 0.75}, {0, 1.0},  {180, 1.0}};
  const double bearing = kSpots[k % kMaxEscorts][0] * M_PI / 180.0;
  const double distance = kSpots[k % kMaxEscorts][1];
  return distance * Vector2d(std::cos(bearing), std::sin(bearing));
}

void AddEscorts(int count, uint64_t seed, Scene* scene) {
  if (count <= 0) return;
  SimRandom rng(HashCombine(seed, 0xe5c0));
  Material plain;
  plain.color = Vector3f(0.75f, 0.55f, 0.45f);
  const int skin = scene->AddMaterial(plain);
  plain.color = Vector3f(0.12f, 0.12f, 0.18f);
  const int trousers = scene->AddMaterial(plain);
  for (int k = 0; k < std::min(count, kMaxEscorts); ++k) {
    Material cloth;
    cloth.texture = scene->AddTexture(Texture(MakeClothTexture(rng.Next())));
    cloth.color = Vector3f(1.0f, 1.0f, 1.0f);
    const float height = static_cast<float>(rng.Uniform(1.6, 1.9));
    const Mesh body = MakePedestrian(scene->AddMaterial(cloth), trousers, skin, 0.0f, height, rng.Next());
    CarriedPlacement placement;
    placement.spot = EscortSpot(k);
    placement.sway = 0.05;
    placement.bob = 0.03;
    placement.yaw_swing_deg = 6.0;
    placement.stride_period = rng.Uniform(1.0, 1.2);
    placement.phase = rng.Uniform(0.0, 2.0 * M_PI);
    scene->AddCarriedObject(body, placement);
  }
}

std::vector<Vector2d> LoopRouteJunctions(const TownLayout& layout, int i0, int j0, int i1, int j1) {
  std::vector<Vector2d> points;
  for (int i = i0; i < i1; ++i) points.push_back(layout.Junction(i, j0));
  for (int j = j0; j < j1; ++j) points.push_back(layout.Junction(i1, j));
  for (int i = i1; i > i0; --i) points.push_back(layout.Junction(i, j1));
  for (int j = j1; j > j0; --j) points.push_back(layout.Junction(i0, j));
  points.push_back(layout.Junction(i0, j0));
  return points;
}

std::vector<Vector2d> FigureEightJunctions(const TownLayout& layout, int i0, int j0) {
  const int steps[][2] = {{1, 0}, {1, 1}, {1, 2}, {0, 2}, {0, 1}, {1, 1}, {2, 1}, {2, 0}, {1, 0}};
  std::vector<Vector2d> points;
  for (const auto& [di, dj] : steps) points.push_back(layout.Junction(i0 + di, j0 + dj));
  return points;
}

std::vector<Vector2d> RandomRouteJunctions(const TownLayout& layout, int num_segments, uint64_t seed) {
  SimRandom rng(HashCombine(seed, 0x7047e));
  const int nx = static_cast<int>(layout.street_x.size()), ny = static_cast<int>(layout.street_y.size());
  int i = std::min(1, nx - 1), j = 0, di = 1, dj = 0;
  std::vector<Vector2d> points = {layout.Junction(i, j)};
  std::set<std::tuple<int, int, int, int>> used;
  for (int s = 0; s < num_segments; ++s) {
    // Candidate directions: straight, left, right (no U-turns), inside the grid; prefer unused streets.
    const int dirs[3][2] = {{di, dj}, {-dj, di}, {dj, -di}};
    std::vector<int> options, fresh;
    for (int k = 0; k < 3; ++k) {
      const int ni = i + dirs[k][0], nj = j + dirs[k][1];
      if (ni < 0 || nj < 0 || ni >= nx || nj >= ny) continue;
      options.push_back(k);
      if (!used.count({std::min(i, ni), std::min(j, nj), std::max(i, ni), std::max(j, nj)})) fresh.push_back(k);
    }
    if (options.empty()) break;
    const std::vector<int>& pool = fresh.empty() ? options : fresh;
    // Straight ahead twice as likely as a turn.
    std::vector<int> weighted;
    for (int k : pool) {
      weighted.push_back(k);
      if (k == 0) weighted.push_back(k);
    }
    const int k = weighted[rng.Int(0, static_cast<int>(weighted.size()) - 1)];
    const int ni = i + dirs[k][0], nj = j + dirs[k][1];
    used.insert({std::min(i, ni), std::min(j, nj), std::max(i, ni), std::max(j, nj)});
    di = dirs[k][0];
    dj = dirs[k][1];
    i = ni;
    j = nj;
    points.push_back(layout.Junction(i, j));
  }
  return points;
}

bool TownLayout::OnStreets(const Vector2d& p) const {
  if (street_x.empty() || street_y.empty()) return false;
  const double half = road_width / 2.0 + sidewalk_width;
  const auto [x_min, x_max] = std::minmax_element(street_x.begin(), street_x.end());
  const auto [y_min, y_max] = std::minmax_element(street_y.begin(), street_y.end());
  if (p.x() < *x_min - half || p.x() > *x_max + half || p.y() < *y_min - half || p.y() > *y_max + half) return false;
  const auto near_one = [half](const std::vector<double>& lines, double v) {
    return std::any_of(lines.begin(), lines.end(), [&](double line) { return std::abs(v - line) <= half; });
  };
  return near_one(street_x, p.x()) || near_one(street_y, p.y());
}

std::vector<Vector2d> OffsetPolyline(const std::vector<Vector2d>& points, double offset) {
  const size_t n = points.size();
  if (n < 2) return points;
  const bool closed = (points.front() - points.back()).norm() < 1e-9;
  auto right = [](const Vector2d& d) { return Vector2d(d.y(), -d.x()); };
  std::vector<Vector2d> out(n);
  for (size_t k = 0; k < n; ++k) {
    Vector2d d_in, d_out;
    if (k == 0) {
      d_out = (points[1] - points[0]).normalized();
      d_in = closed ? Vector2d((points[0] - points[n - 2]).normalized()) : d_out;
    } else if (k + 1 == n) {
      d_in = (points[k] - points[k - 1]).normalized();
      d_out = closed ? Vector2d((points[1] - points[0]).normalized()) : d_in;
    } else {
      d_in = (points[k] - points[k - 1]).normalized();
      d_out = (points[k + 1] - points[k]).normalized();
    }
    const Vector2d r1 = right(d_in), r2 = right(d_out);
    const double denom = std::max(0.1, 1.0 + r1.dot(r2));
    out[k] = points[k] + offset * (r1 + r2) / denom;
  }
  return out;
}

}  // namespace retrace
