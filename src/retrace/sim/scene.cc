#include "retrace/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include <Eigen/Dense>

#include "retrace/sim/procedural_texture.h"

namespace retrace {

void Mesh::AddTriangle(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector2f& uv0,
                       const Vector2f& uv1, const Vector2f& uv2, int material, int face) {
  // Degenerate triangles cannot be hit and have no texture mapping; skip them.
  if ((p1 - p0).cross(p2 - p0).squaredNorm() < 1e-14f) return;
  vertices_.insert(vertices_.end(), {p0, p1, p2});
  uvs_.insert(uvs_.end(), {uv0, uv1, uv2});
  materials_.push_back(material);
  faces_.push_back(face >= 0 ? face : next_face_++);
}

void Mesh::AddQuad(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector3f& p3,
                   const Vector2f& uv0, const Vector2f& uv1, const Vector2f& uv2, const Vector2f& uv3, int material) {
  const int face = next_face_++;
  AddTriangle(p0, p1, p2, uv0, uv1, uv2, material, face);
  AddTriangle(p0, p2, p3, uv0, uv2, uv3, material, face);
}

void Mesh::AddTiledQuad(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector3f& p3,
                        float tile_u_m, float tile_v_m, int material, const Vector2f& uv_offset) {
  const float lu = (p1 - p0).norm() / tile_u_m;
  const float lv = (p3 - p0).norm() / tile_v_m;
  AddQuad(p0, p1, p2, p3, uv_offset, uv_offset + Vector2f(lu, 0), uv_offset + Vector2f(lu, lv),
          uv_offset + Vector2f(0, lv), material);
}

void Mesh::AddBox(const Vector3f& lo, const Vector3f& hi, float tile_m, int material) {
  const Vector3f c[8] = {{lo.x(), lo.y(), lo.z()}, {hi.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), lo.z()},
                         {lo.x(), hi.y(), lo.z()}, {lo.x(), lo.y(), hi.z()}, {hi.x(), lo.y(), hi.z()},
                         {hi.x(), hi.y(), hi.z()}, {lo.x(), hi.y(), hi.z()}};
  // Side faces: top edge first so that v grows downwards like image rows.
  AddTiledQuad(c[4], c[5], c[1], c[0], tile_m, tile_m, material);  // south (y = lo)
  AddTiledQuad(c[5], c[6], c[2], c[1], tile_m, tile_m, material);  // east
  AddTiledQuad(c[6], c[7], c[3], c[2], tile_m, tile_m, material);  // north
  AddTiledQuad(c[7], c[4], c[0], c[3], tile_m, tile_m, material);  // west
  AddTiledQuad(c[4], c[5], c[6], c[7], tile_m, tile_m, material);  // top
  AddTiledQuad(c[0], c[1], c[2], c[3], tile_m, tile_m, material);  // bottom
}

namespace {

// Texture coordinates of a point on a triangle by projecting on the two axes most parallel to its plane.
Vector2f PlanarUv(const Vector3f& p, const Vector3f& normal, float tile_m) {
  const Vector3f n = normal.cwiseAbs();
  if (n.z() >= n.x() && n.z() >= n.y()) return Vector2f(p.x(), p.y()) / tile_m;
  if (n.x() >= n.y()) return Vector2f(p.y(), -p.z()) / tile_m;
  return Vector2f(p.x(), -p.z()) / tile_m;
}

}  // namespace

void Mesh::AddBlob(const Vector3f& centre, const Vector3f& radii, int subdivisions, float roughness, uint64_t seed,
                   float tile_m, int material) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<Vector3f> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                             {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      midpoint[key] = static_cast<int>(v.size()) - 1;
      return static_cast<int>(v.size()) - 1;
    };
    std::vector<Eigen::Vector3i> next;
    for (const auto& tri : f) {
      const int a = mid(tri[0], tri[1]), b = mid(tri[1], tri[2]), c = mid(tri[2], tri[0]);
      next.insert(next.end(), {{tri[0], a, c}, {tri[1], b, a}, {tri[2], c, b}, {a, b, c}});
    }
    f = next;
  }
  std::vector<Vector3f> p(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    const float bump = 1.0f + roughness * static_cast<float>(2.0 * HashToUnit(HashCombine(seed, i)) - 1.0);
    p[i] = centre + bump * v[i].cwiseProduct(radii);
  }
  for (const auto& tri : f) {
    const Vector3f& a = p[tri[0]];
    const Vector3f& b = p[tri[1]];
    const Vector3f& c = p[tri[2]];
    const Vector3f n = (b - a).cross(c - a);
    AddTriangle(a, b, c, PlanarUv(a, n, tile_m), PlanarUv(b, n, tile_m), PlanarUv(c, n, tile_m), material);
  }
}

void Mesh::AddCylinder(const Vector3f& base, float radius, float height, int sides, float tile_u_m, float tile_v_m,
                       int material) {
  const float circumference = 2.0f * static_cast<float>(M_PI) * radius;
  for (int i = 0; i < sides; ++i) {
    const float a0 = 2.0f * static_cast<float>(M_PI) * i / sides;
    const float a1 = 2.0f * static_cast<float>(M_PI) * (i + 1) / sides;
    const Vector3f d0(std::cos(a0), std::sin(a0), 0), d1(std::cos(a1), std::sin(a1), 0);
    const Vector3f top(0, 0, height);
    const float u0 = circumference * i / sides / tile_u_m, u1 = circumference * (i + 1) / sides / tile_u_m;
    AddQuad(base + radius * d0 + top, base + radius * d1 + top, base + radius * d1, base + radius * d0,
            Vector2f(u0, 0), Vector2f(u1, 0), Vector2f(u1, height / tile_v_m), Vector2f(u0, height / tile_v_m),
            material);
  }
}

void Mesh::AddDisc(const Vector3f& centre, const Vector3f& normal, float radius, int sides, int material) {
  const Vector3f n = normal.normalized();
  const Vector3f a = n.unitOrthogonal();
  const Vector3f b = n.cross(a);
  const int face = next_face_++;
  for (int i = 0; i < sides; ++i) {
    const float a0 = 2.0f * static_cast<float>(M_PI) * i / sides;
    const float a1 = 2.0f * static_cast<float>(M_PI) * (i + 1) / sides;
    AddTriangle(centre, centre + radius * (std::cos(a0) * a + std::sin(a0) * b),
                centre + radius * (std::cos(a1) * a + std::sin(a1) * b), Vector2f(0.5f, 0.5f), Vector2f(0.5f, 0.5f),
                Vector2f(0.5f, 0.5f), material, face);
  }
}

void Mesh::Append(const Mesh& other, const Rigid3d& transform) {
  const Eigen::Matrix3f r = transform.rotation.cast<float>();
  const Vector3f t = transform.translation.cast<float>();
  const int face_base = next_face_;
  int max_face = -1;
  for (size_t i = 0; i < other.num_triangles(); ++i) {
    vertices_.push_back(r * other.vertices_[3 * i] + t);
    vertices_.push_back(r * other.vertices_[3 * i + 1] + t);
    vertices_.push_back(r * other.vertices_[3 * i + 2] + t);
    uvs_.insert(uvs_.end(), {other.uvs_[3 * i], other.uvs_[3 * i + 1], other.uvs_[3 * i + 2]});
    materials_.push_back(other.materials_[i]);
    faces_.push_back(face_base + other.faces_[i]);
    max_face = std::max(max_face, other.faces_[i]);
  }
  next_face_ = face_base + max_face + 1;
}

Rigid3d ScriptedPath::PoseAt(double time) const {
  std::vector<double> cumulative(1, 0.0);
  std::vector<Vector2d> pts = points;
  if (loop && pts.size() > 2) pts.push_back(pts.front());
  for (size_t i = 1; i < pts.size(); ++i) cumulative.push_back(cumulative.back() + (pts[i] - pts[i - 1]).norm());
  const double total = cumulative.back();
  double s = start_offset + speed * time;
  double direction = 1.0;
  if (total <= 0.0) {
    s = 0.0;
  } else if (loop) {
    s = std::fmod(s, total);
    if (s < 0) s += total;
  } else {
    double m = std::fmod(s, 2.0 * total);
    if (m < 0) m += 2.0 * total;
    if (m > total) {
      s = 2.0 * total - m;
      direction = -1.0;
    } else {
      s = m;
    }
  }
  size_t i = 1;
  while (i + 1 < pts.size() && cumulative[i] < s) ++i;
  const double len = std::max(1e-9, cumulative[i] - cumulative[i - 1]);
  const double a = std::clamp((s - cumulative[i - 1]) / len, 0.0, 1.0);
  const Vector2d p = pts[i - 1] + a * (pts[i] - pts[i - 1]);
  const Vector2d d = direction * (pts[i] - pts[i - 1]).normalized();
  Matrix3d r;
  r << d.x(), -d.y(), 0, d.y(), d.x(), 0, 0, 0, 1;
  return Rigid3d(r, Vector3d(p.x(), p.y(), 0.0));
}

Rigid3d CarriedPlacement::PoseAt(double time) const {
  // One stride: the body swings sideways once and forwards, backwards and up twice (once per step).
  const double a = 2.0 * M_PI * time / stride_period + phase;
  const double yaw = yaw_swing_deg * M_PI / 180.0 * std::sin(a);
  const Vector3d position(spot.x() + 0.5 * sway * std::sin(2.0 * a), spot.y() + sway * std::sin(a),
                          bob * 0.5 * (1.0 - std::cos(2.0 * a)));
  return Rigid3d(Eigen::AngleAxisd(yaw, Vector3d::UnitZ()).toRotationMatrix(), position);
}

Scene::Scene() {
  // One build thread: the per-frame rebuild of the tiny top-level structure must not wake Embree's worker threads,
  // which would spin on the cores the renderer's own threads need.
  device_ = rtcNewDevice("threads=1");
  if (!device_) throw std::runtime_error("cannot create an Embree device");
  scene_ = rtcNewScene(device_);
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC);
  static_scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(static_scene_, RTC_BUILD_QUALITY_HIGH);
}

Scene::~Scene() {
  for (auto& m : moving_) {
    if (m.prototype) rtcReleaseScene(m.prototype);
  }
  if (scene_) rtcReleaseScene(scene_);
  if (static_scene_) rtcReleaseScene(static_scene_);
  if (device_) rtcReleaseDevice(device_);
}

int Scene::AddTexture(Texture texture) {
  textures_.push_back(std::move(texture));
  return static_cast<int>(textures_.size()) - 1;
}

int Scene::AddMaterial(const Material& material) {
  materials_.push_back(material);
  return static_cast<int>(materials_.size()) - 1;
}

std::vector<TriangleShading> Scene::ComputeShading(const Mesh& mesh) {
  std::vector<TriangleShading> out(mesh.num_triangles());
  for (size_t i = 0; i < mesh.num_triangles(); ++i) {
    const Vector3f& p0 = mesh.vertices()[3 * i];
    const Vector3f e1 = mesh.vertices()[3 * i + 1] - p0;
    const Vector3f e2 = mesh.vertices()[3 * i + 2] - p0;
    const Vector2f& uv0 = mesh.uvs()[3 * i];
    const Vector2f d1 = mesh.uvs()[3 * i + 1] - uv0;
    const Vector2f d2 = mesh.uvs()[3 * i + 2] - uv0;
    // Gradients in the plane of the triangle: g = a e1 + b e2 with g.e1 = d1, g.e2 = d2 (per uv component).
    Eigen::Matrix2d gram;
    gram << e1.dot(e1), e1.dot(e2), e1.dot(e2), e2.dot(e2);
    const Eigen::Matrix2d inv = gram.inverse();
    const Eigen::Vector2d cu = inv * Eigen::Vector2d(d1.x(), d2.x());
    const Eigen::Vector2d cv = inv * Eigen::Vector2d(d1.y(), d2.y());
    TriangleShading& s = out[i];
    s.p0 = p0;
    s.normal = e1.cross(e2).normalized();
    s.uv0 = uv0;
    s.grad_u = static_cast<float>(cu.x()) * e1 + static_cast<float>(cu.y()) * e2;
    s.grad_v = static_cast<float>(cv.x()) * e1 + static_cast<float>(cv.y()) * e2;
    s.material = mesh.materials()[i];
    s.face = mesh.faces()[i];
  }
  return out;
}

RTCGeometry Scene::MakeTriangleGeometry(const Mesh& mesh) const {
  RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  const size_t n = mesh.num_triangles();
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n + 1));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
  for (size_t i = 0; i < 3 * n; ++i) {
    vertices[3 * i] = mesh.vertices()[i].x();
    vertices[3 * i + 1] = mesh.vertices()[i].y();
    vertices[3 * i + 2] = mesh.vertices()[i].z();
    indices[i] = static_cast<unsigned>(i);
  }
  rtcCommitGeometry(geometry);
  return geometry;
}

void Scene::AddStaticMesh(const Mesh& mesh) {
  if (mesh.num_triangles() == 0) return;
  RTCGeometry geometry = MakeTriangleGeometry(mesh);
  const unsigned id = rtcAttachGeometry(static_scene_, geometry);
  rtcReleaseGeometry(geometry);
  if (static_shading_.size() <= id) static_shading_.resize(id + 1);
  static_shading_[id] = ComputeShading(mesh);
  committed_ = false;
}

void Scene::AddMovingObject(const Mesh& mesh, const ScriptedPath& path) {
  if (mesh.num_triangles() == 0) return;
  AddInstance(mesh).path = path;
}

void Scene::AddCarriedObject(const Mesh& mesh, const CarriedPlacement& placement) {
  if (mesh.num_triangles() == 0) return;
  MovingObject& object = AddInstance(mesh);
  object.carried = true;
  object.placement = placement;
}

size_t Scene::num_carried_objects() const {
  return static_cast<size_t>(
      std::count_if(moving_.begin(), moving_.end(), [](const MovingObject& object) { return object.carried; }));
}

Scene::MovingObject& Scene::AddInstance(const Mesh& mesh) {
  MovingObject object;
  object.prototype = rtcNewScene(device_);
  RTCGeometry geometry = MakeTriangleGeometry(mesh);
  rtcAttachGeometry(object.prototype, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(object.prototype);
  object.instance = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(object.instance, object.prototype);
  object.geom_id = rtcAttachGeometry(scene_, object.instance);
  rtcReleaseGeometry(object.instance);
  object.shading = ComputeShading(mesh);
  if (moving_of_geom_.size() <= object.geom_id) moving_of_geom_.resize(object.geom_id + 1, -1);
  moving_of_geom_[object.geom_id] = static_cast<int>(moving_.size());
  moving_.push_back(std::move(object));
  committed_ = false;
  return moving_.back();
}

size_t Scene::num_static_triangles() const {
  size_t n = 0;
  for (const auto& s : static_shading_) n += s.size();
  return n;
}

void Scene::SetTime(double time) {
  if (committed_) {
    UpdateTopLevel(time);
  } else {
    time_ = time;
    Commit();
  }
}

void Scene::UpdateTopLevel(double time) {
  time_ = time;
  for (auto& object : moving_) {
    object.town_from_object =
        object.carried ? town_from_carrier_ * object.placement.PoseAt(time) : object.path.PoseAt(time);
    float xfm[12];
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) xfm[3 * c + r] = static_cast<float>(object.town_from_object.rotation(r, c));
    }
    for (int r = 0; r < 3; ++r) xfm[9 + r] = static_cast<float>(object.town_from_object.translation(r));
    rtcSetGeometryTransform(object.instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
    rtcCommitGeometry(object.instance);
  }
  rtcCommitScene(scene_);
  RTCBounds static_bounds, moving_bounds;
  rtcGetSceneBounds(static_scene_, &static_bounds);
  rtcGetSceneBounds(scene_, &moving_bounds);
  // An empty scene reports inverted (-inf upper) bounds; max() ignores it.
  top_ = std::max(static_bounds.upper_z, moving_bounds.upper_z) + 0.01f;
}

void Scene::Commit() {
  rtcCommitScene(static_scene_);
  committed_ = true;
  UpdateTopLevel(time_);
}

const TriangleShading& Scene::Shading(unsigned geom_id, unsigned inst_id, unsigned prim_id,
                                      const Rigid3d** town_from_object) const {
  if (inst_id != RTC_INVALID_GEOMETRY_ID) {
    const MovingObject& object = moving_[moving_of_geom_[inst_id]];
    *town_from_object = &object.town_from_object;
    return object.shading[prim_id];
  }
  *town_from_object = nullptr;
  return static_shading_[geom_id][prim_id];
}

unsigned Scene::ObjectKey(unsigned geom_id, unsigned inst_id) const {
  return inst_id != RTC_INVALID_GEOMETRY_ID ? 0x10000u + inst_id : geom_id + 1;
}

}  // namespace retrace
