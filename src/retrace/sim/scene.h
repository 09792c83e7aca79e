#pragma once

// The simulated world: textured triangle meshes in an Embree scene, static ones and moving ones (pedestrians, cars
// on scripted paths), plus the sky.
//
// World frame of the simulator ("town frame"): X east, Y north, Z up, metres; the ground is the plane Z = 0.
// (Sequences written to disk use a camera-style world frame instead, see simulator.h.)
//
// Every triangle is planar-mapped: its texture coordinates are an affine function of the position on its plane,
// uv(p) = uv0 + G (p - p0) with the 2x3 gradient G computed once per triangle. The renderer evaluates uv at the hit
// point directly and maps the pixel footprint (a world-space ellipse from ray differentials) through G to texture
// space for filtering.

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <embree3/rtcore.h>

#include "retrace/sim/texture.h"
#include "retrace/util/types.h"

namespace retrace {

struct Material {
  // Index of a texture of the scene, or -1 for a uniform colour.
  int texture = -1;
  // Reflectance multiplier of the texture (a tint) or the uniform reflectance when texture = -1.
  Vector3f color = Vector3f(0.7f, 0.7f, 0.7f);
  // Emissive materials show `color` as radiance regardless of sun and shadows (calibration markers).
  bool emissive = false;
};

// Triangles under construction, each with its own three vertices and texture coordinates.
class Mesh {
 public:
  // Adds a triangle; `face` groups triangles of one planar polygon (anti-aliasing looks for face changes), -1 = new.
  void AddTriangle(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector2f& uv0,
                   const Vector2f& uv1, const Vector2f& uv2, int material, int face = -1);
  // Adds the planar quad p0 p1 p2 p3 (counter-clockwise seen from the side it faces) as two triangles.
  void AddQuad(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector3f& p3, const Vector2f& uv0,
               const Vector2f& uv1, const Vector2f& uv2, const Vector2f& uv3, int material);
  // A quad with texture coordinates in metres divided by `tile_m` (u along p0->p1, v along p0->p3, v downwards
  // when p3 is below p0): for walls and ground with textures that cover tile_u_m x tile_v_m metres.
  void AddTiledQuad(const Vector3f& p0, const Vector3f& p1, const Vector3f& p2, const Vector3f& p3, float tile_u_m,
                    float tile_v_m, int material, const Vector2f& uv_offset = Vector2f::Zero());
  // An axis-aligned box (all six faces outwards) with the same material and tiled mapping on every face.
  void AddBox(const Vector3f& lo, const Vector3f& hi, float tile_m, int material);
  // A closed polyhedral approximation of a sphere-like blob (an icosphere subdivided `subdivisions` times) with radii
  // `radii`, its vertices pushed by `roughness` x radius of seeded noise; planar-per-triangle texture mapping.
  void AddBlob(const Vector3f& centre, const Vector3f& radii, int subdivisions, float roughness, uint64_t seed,
               float tile_m, int material);
  // A vertical cylinder (n sides, no caps needed for trunks and poles) from z0 to z1.
  void AddCylinder(const Vector3f& base, float radius, float height, int sides, float tile_u_m, float tile_v_m,
                   int material);
  // A flat disc facing direction `normal` (a calibration marker), as `sides` triangles around its centre.
  void AddDisc(const Vector3f& centre, const Vector3f& normal, float radius, int sides, int material);
  // Appends all triangles of `other`, transformed by `transform`.
  void Append(const Mesh& other, const Rigid3d& transform);

  size_t num_triangles() const { return materials_.size(); }
  const std::vector<Vector3f>& vertices() const { return vertices_; }
  const std::vector<Vector2f>& uvs() const { return uvs_; }
  const std::vector<int>& materials() const { return materials_; }
  const std::vector<int>& faces() const { return faces_; }

 private:
  std::vector<Vector3f> vertices_;  // 3 per triangle
  std::vector<Vector2f> uvs_;       // 3 per triangle
  std::vector<int> materials_;      // 1 per triangle
  std::vector<int> faces_;          // 1 per triangle
  int next_face_ = 0;
};

// A path on the ground followed at constant speed by a moving object: position and heading at any time.
struct ScriptedPath {
  std::vector<Vector2d> points;  // ground positions (town frame X, Y), at least 2
  double speed = 1.4;             // m/s
  double start_offset = 0.0;      // arc length (m) at time 0
  bool loop = true;               // loop back to the first point (else go back and forth)

  // town_from_object at `time`: object x axis along the direction of motion, z up.
  Rigid3d PoseAt(double time) const;
};

// Where an object carried along with the camera stands at a time (an escort walking beside the car, Booij 2007
// §B.5.4): a fixed spot of the carrier frame (Scene::SetCarrier: x forward, y left, z up, origin on the ground below
// the camera) plus the periodic swing of a walk, so that it does not move rigidly with the camera.
struct CarriedPlacement {
  Vector2d spot = Vector2d::Zero();  // metres, carrier frame
  double sway = 0.0;           // amplitude (m) of the sideways swing; the swing forwards and backwards is half of it
  double bob = 0.0;            // height (m) of the up-and-down motion, twice per stride (never below the ground)
  double yaw_swing_deg = 0.0;  // amplitude of the turn of the body about the vertical
  double stride_period = 1.1;  // seconds of one stride (two steps), > 0
  double phase = 0.0;          // radians into the stride at time 0

  // carrier_from_object at `time`: object x axis along the carrier's (walking with it), z up.
  Rigid3d PoseAt(double time) const;
};

// Per-triangle data for shading, precomputed when a mesh enters the scene.
struct TriangleShading {
  Vector3f p0;
  Vector3f normal;    // unit, in the mesh frame
  Vector2f uv0;
  Vector3f grad_u;    // uv(p) = uv0 + (grad_u . (p - p0), grad_v . (p - p0))
  Vector3f grad_v;
  int material = 0;
  int face = 0;
};

enum class SkyType { kProcedural, kUniform };

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  int AddTexture(Texture texture);
  int AddMaterial(const Material& material);
  // Static geometry (in the town frame).
  void AddStaticMesh(const Mesh& mesh);
  // A rigid object (mesh in its own frame: x forward, y left, z up) that moves along `path`.
  void AddMovingObject(const Mesh& mesh, const ScriptedPath& path);
  // A rigid object (mesh in its own frame: x forward, y left, z up) carried along with the camera: at every SetTime
  // it is placed at town_from_carrier * placement.PoseAt(time), with the carrier of the last SetCarrier.
  void AddCarriedObject(const Mesh& mesh, const CarriedPlacement& placement);
  // The carrier of the carried objects (town_from_carrier: x forward, y left, z up, origin on the ground), used from
  // the next SetTime on. Identity until set.
  void SetCarrier(const Rigid3d& town_from_carrier) { town_from_carrier_ = town_from_carrier; }

  // Builds the acceleration structures; called by SetTime when geometry was added since the last build.
  void Commit();
  // Places the moving objects at `time` (seconds), the carried ones on the current carrier, and updates the
  // acceleration structure.
  void SetTime(double time);
  double time() const { return time_; }

  void set_sky(SkyType type, const Vector3f& uniform_color = Vector3f::Zero()) {
    sky_type_ = type;
    sky_color_ = uniform_color;
  }
  SkyType sky_type() const { return sky_type_; }
  // Cloud layer of the procedural sky: a tiling texture of cloud cover (red channel), mapped on a plane above.
  void set_clouds(Texture clouds) { clouds_ = std::move(clouds); }
  const Texture& clouds() const { return clouds_; }
  const Vector3f& sky_color() const { return sky_color_; }

  // Rays are traced against both Embree scenes (the static one first; a second query on the same rays keeps the
  // nearer hit): the static triangles without an instance level, the moving objects as instances.
  RTCScene static_embree_scene() const { return static_scene_; }
  RTCScene moving_embree_scene() const { return scene_; }
  // Highest point of all geometry (town frame Z): rays towards the sun need not go further up.
  float top() const { return top_; }
  const std::vector<Texture>& textures() const { return textures_; }
  const std::vector<Material>& materials() const { return materials_; }
  size_t num_static_triangles() const;
  // Moving objects, the carried ones included.
  size_t num_moving_objects() const { return moving_.size(); }
  size_t num_carried_objects() const;

  // Shading data of a hit: `geom_id`/`prim_id` from Embree and `inst_id` (RTC_INVALID_GEOMETRY_ID for static
  // geometry). `town_from_object` receives the placement of a moving object (nullptr for static geometry).
  const TriangleShading& Shading(unsigned geom_id, unsigned inst_id, unsigned prim_id,
                                 const Rigid3d** town_from_object) const;
  // A small integer naming the object hit (for anti-aliasing edge detection).
  unsigned ObjectKey(unsigned geom_id, unsigned inst_id) const;

 private:
  struct MovingObject {
    RTCScene prototype = nullptr;
    RTCGeometry instance = nullptr;
    unsigned geom_id = 0;  // of the instance in the top scene
    std::vector<TriangleShading> shading;
    ScriptedPath path;            // of an object moving on its own
    bool carried = false;         // placed on the carrier by `placement` instead of `path`
    CarriedPlacement placement;
    Rigid3d town_from_object;
  };
  RTCGeometry MakeTriangleGeometry(const Mesh& mesh) const;
  MovingObject& AddInstance(const Mesh& mesh);
  void UpdateTopLevel(double time);
  static std::vector<TriangleShading> ComputeShading(const Mesh& mesh);

  RTCDevice device_ = nullptr;
  // Moving objects: one instance per object in a scene of its own, so that motion only rebuilds this tiny
  // structure. The static geometry is a separate scene, built once.
  RTCScene scene_ = nullptr;
  RTCScene static_scene_ = nullptr;
  std::vector<Texture> textures_;
  std::vector<Material> materials_;
  std::vector<std::vector<TriangleShading>> static_shading_;  // indexed by geometry id in static_scene_
  std::vector<int> moving_of_geom_;                            // top-level geometry id -> moving index or -1
  std::vector<MovingObject> moving_;
  SkyType sky_type_ = SkyType::kProcedural;
  Vector3f sky_color_ = Vector3f::Zero();
  Texture clouds_;
  double time_ = 0.0;
  float top_ = std::numeric_limits<float>::infinity();
  bool committed_ = false;
  Rigid3d town_from_carrier_;
  Rigid3d identity_;
};

}  // namespace retrace
