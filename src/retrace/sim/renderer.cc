#include "retrace/sim/renderer.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <cmath>
#include <functional>
#include <thread>

#include "retrace/sim/procedural_texture.h"

namespace retrace {
namespace {

constexpr int kTileSize = 16;
constexpr int kBatchSize = 256;
constexpr float kInfinity = std::numeric_limits<float>::infinity();

}  // namespace

// Persistent helper threads for Renderer (one pool per renderer, started once): a parallel loop costs a wake-up,
// not a thread start. Run(n, fn) runs fn(i) for i in [0, n) with work stealing by an atomic counter. The caller
// works too and returns as soon as every item is done: it never waits for a helper that the OS has not scheduled
// yet (on a busy machine that wait would cost more than the work). A late helper finds the items taken and goes
// back to sleep; it only touches the job it holds a reference to.
class Renderer::WorkerPool {
 public:
  explicit WorkerPool(int threads) {
    for (int t = 1; t < threads; ++t) workers_.emplace_back([this]() { WorkerLoop(); });
  }
  ~WorkerPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& worker : workers_) worker.join();
  }

  void Run(int n, const std::function<void(int)>& fn) {
    if (workers_.empty() || n <= 1) {
      for (int i = 0; i < n; ++i) fn(i);
      return;
    }
    auto job = std::make_shared<Job>();
    job->n = n;
    job->fn = &fn;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      job_ = job;
      ++generation_;
    }
    wake_.notify_all();
    Work(*job);
    std::unique_lock<std::mutex> lock(job->mutex);
    job->finished.wait(lock, [&]() { return job->done.load() == n; });
  }

 private:
  struct Job {
    std::atomic<int> next{0};
    std::atomic<int> done{0};
    int n = 0;
    const std::function<void(int)>* fn = nullptr;  // valid while items are left (the caller waits for them)
    std::mutex mutex;
    std::condition_variable finished;
  };

  static void Work(Job& job) {
    for (int i = job.next++; i < job.n; i = job.next++) {
      (*job.fn)(i);
      if (++job.done == job.n) {
        std::lock_guard<std::mutex> lock(job.mutex);
        job.finished.notify_all();
      }
    }
  }

  void WorkerLoop() {
    uint64_t seen = 0;
    while (true) {
      std::shared_ptr<Job> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&]() { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
        job = job_;
      }
      Work(*job);
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::shared_ptr<Job> job_;
  uint64_t generation_ = 0;
  bool stop_ = false;
};

namespace {

// Scratch arrays of one ray batch, one set per thread (static storage: no allocation per tile).
struct Batch {
  Vector3f dirs[kBatchSize], diff_x[kBatchSize], diff_y[kBatchSize], colors[kBatchSize];
  uint32_t keys[kBatchSize];
};

Batch& ThreadBatch() {
  static thread_local Batch batch;
  return batch;
}

// 8-bit value of linear intensity v in [0, 1] through the gamma 1/2.2 response, tabulated.
class ResponseCurve {
 public:
  static constexpr int kSize = 65536;
  ResponseCurve() : table_(kSize) {
    for (int i = 0; i < kSize; ++i) table_[i] = 255.0f * std::pow(static_cast<float>(i) / (kSize - 1), 1.0f / 2.2f);
  }
  float operator()(float v) const {
    const int i = static_cast<int>(std::min(1.0f, std::max(0.0f, v)) * (kSize - 1) + 0.5f);
    return table_[i];
  }

 private:
  std::vector<float> table_;
};

const ResponseCurve& Response() {
  static const ResponseCurve curve;
  return curve;
}

// Approximately standard normal from one hash: the sum of four 16-bit uniforms (Irwin-Hall), scaled to unit
// variance. Cheap, deterministic, and bounded at +-3.46 sigma.
float HashGaussian(uint64_t h) {
  float sum = 0.0f;
  for (int i = 0; i < 4; ++i) sum += static_cast<float>((h >> (16 * i)) & 0xffff) * (1.0f / 65535.0f);
  return (sum - 2.0f) * 1.7320508f;
}

float Smoothstep(float a, float b, float x) {
  const float t = std::min(1.0f, std::max(0.0f, (x - a) / (b - a)));
  return t * t * (3.0f - 2.0f * t);
}

}  // namespace

Vector3d Lighting::SunDirection() const {
  const double az = sun_azimuth_deg * M_PI / 180.0;
  const double el = sun_elevation_deg * M_PI / 180.0;
  return Vector3d(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
}

struct Renderer::Frame {
  const Scene* scene;
  Eigen::Matrix3f rotation;  // town_from_cam
  Vector3f origin;
  Vector3f sun;
  bool sun_up;
  bool gray;  // grey output: textures are sampled on their luminance only
  float sun_irradiance;
  float sky_irradiance;
  float exposure;  // exposure x gain
  int width, height, tiles_x, tiles_y;
  // Per pixel: linear radiance, what was hit (object, face, shadow bit) and the noise-free 8-bit luminance (the
  // renderer's buffers; pixels without a ray keep black, "nothing" and 0 from the constructor).
  Vector3f* color;
  uint32_t* key;
  float* level;
};

// A pixel's ray in the camera frame: bearing and its differentials to the right and lower neighbours.
struct Renderer::PixelRay {
  Vector3f bearing, diff_x, diff_y;
  int pixel;
};

Renderer::Renderer(const CameraModel& camera, const RenderOptions& options)
    : camera_(camera.Clone()), options_(options), pool_(std::make_unique<WorkerPool>(options.num_threads)) {
  const int w = camera.width(), h = camera.height();
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<PixelRay> rays(n);
  valid_.assign(n, 0);
  const int ss = options.antialiasing;
  const bool quincunx = ss == 2;
  sub_bearings_.assign(ss > 2 ? n * ss * ss : 0, Vector3f::Zero());
  auto unproject = [&](double x, double y, Vector3f* out) {
    Vector3d b;
    if (!camera.Unproject(Vector2d(x, y), &b) || !b.allFinite()) return false;
    *out = b.cast<float>();
    return true;
  };
  pool_->Run(h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      Vector3f b;
      if (!unproject(x, y, &b)) continue;
      valid_[i] = 1;
      rays[i].bearing = b;
      rays[i].pixel = static_cast<int>(i);
      // Differentials by central differences of the model over one pixel (robust at image borders).
      Vector3f l = Vector3f::Zero(), r = l, u = l, d = l;
      const bool has_x = unproject(x - 0.5, y, &l) && unproject(x + 0.5, y, &r);
      const bool has_y = unproject(x, y - 0.5, &u) && unproject(x, y + 0.5, &d);
      rays[i].diff_x = has_x ? Vector3f(r - l) : Vector3f::Zero();
      rays[i].diff_y = has_y ? Vector3f(d - u) : Vector3f::Zero();
      for (int sy = 0; sy < ss && ss > 2; ++sy) {
        for (int sx = 0; sx < ss; ++sx) {
          Vector3f s;
          const double ox = (sx + 0.5) / ss - 0.5, oy = (sy + 0.5) / ss - 0.5;
          sub_bearings_[i * ss * ss + sy * ss + sx] = unproject(x + ox, y + oy, &s) ? s : b;
        }
      }
    }
  });
  // Valid pixels tile by tile: each tile's rays are contiguous in memory.
  const int tiles_x = (w + kTileSize - 1) / kTileSize, tiles_y = (h + kTileSize - 1) / kTileSize;
  ray_of_pixel_.assign(n, -1);
  tile_begin_.assign(1, 0);
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      for (int y = ty * kTileSize; y < std::min(h, (ty + 1) * kTileSize); ++y) {
        for (int x = tx * kTileSize; x < std::min(w, (tx + 1) * kTileSize); ++x) {
          const size_t i = static_cast<size_t>(y) * w + x;
          if (!valid_[i]) continue;
          ray_of_pixel_[i] = static_cast<int>(rays_.size());
          rays_.push_back(rays[i]);
        }
      }
      tile_begin_.push_back(static_cast<int>(rays_.size()));
    }
  }
  color_.assign(n, Vector3f::Zero());
  key_.assign(n, 0xffffffffu);
  level_.assign(n, 0.0f);
  mark_.assign(n, 0);
  if (quincunx) {
    // Pixel corners: corner (x, y) is at pixel coordinates (x - 0.5, y - 0.5), shared by up to four pixels.
    const size_t corners = static_cast<size_t>(w + 1) * (h + 1);
    corner_bearings_.assign(corners, Vector3f::Zero());
    corner_valid_.assign(corners, 0);
    corner_needed_.assign(corners, 0);
    corner_color_.assign(corners, Vector3f::Zero());
    pool_->Run(h + 1, [&](int y) {
      for (int x = 0; x <= w; ++x) {
        const size_t c = static_cast<size_t>(y) * (w + 1) + x;
        corner_valid_[c] = unproject(x - 0.5, y - 0.5, &corner_bearings_[c]);
      }
    });
  }
}

Renderer::~Renderer() = default;

void Renderer::TraceBatch(const Frame& frame, const Vector3f* directions, const Vector3f* diff_x,
                          const Vector3f* diff_y, int count, Vector3f* colors, uint32_t* keys) const {
  const Scene& scene = *frame.scene;
  RTCRayHit rays[kBatchSize];
  RTCRay shadow[kBatchSize];
  int shadow_of[kBatchSize];
  Vector3f albedo[kBatchSize];
  float ambient[kBatchSize], direct[kBatchSize];
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (int i = 0; i < count; ++i) {
    RTCRayHit& r = rays[i];
    r.ray.org_x = frame.origin.x();
    r.ray.org_y = frame.origin.y();
    r.ray.org_z = frame.origin.z();
    r.ray.dir_x = directions[i].x();
    r.ray.dir_y = directions[i].y();
    r.ray.dir_z = directions[i].z();
    r.ray.tnear = 0.0f;
    r.ray.tfar = kInfinity;
    r.ray.time = 0.0f;
    r.ray.mask = 0xffffffffu;
    r.ray.id = i;
    r.ray.flags = 0;
    r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  }
  // Static geometry, then the moving objects (Embree keeps a hit only if it is nearer than tfar).
  rtcIntersect1M(scene.static_embree_scene(), &context, rays, count, sizeof(RTCRayHit));
  if (scene.num_moving_objects() > 0) {
    rtcIntersect1M(scene.moving_embree_scene(), &context, rays, count, sizeof(RTCRayHit));
  }

  int num_shadow = 0;
  const Vector3f sky_color = scene.sky_color();
  for (int i = 0; i < count; ++i) {
    const RTCRayHit& r = rays[i];
    const Vector3f& dir = directions[i];
    direct[i] = 0.0f;
    if (r.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
      keys[i] = 0;
      ambient[i] = -1.0f;  // marks sky
      if (scene.sky_type() == SkyType::kUniform) {
        colors[i] = sky_color;
        continue;
      }
      // Procedural sky: horizon-to-zenith gradient, clouds on a plane above, sun glow and disc.
      const float up = dir.z();
      const float brightness = frame.sky_irradiance / 0.5f;
      const Vector3f horizon(0.78f, 0.82f, 0.88f), zenith(0.28f, 0.42f, 0.72f);
      const float t = std::sqrt(std::max(0.0f, up));
      Vector3f c = up < 0.0f ? Vector3f(0.5f, 0.5f, 0.5f) : Vector3f(horizon * (1.0f - t) + zenith * t);
      if (up > 0.02f && scene.clouds().width() > 0) {
        constexpr float kScale = 0.08f;  // cloud texture tiles per unit of the plane at height 1
        const float inv = 1.0f / up;
        const Vector2f uv(dir.x() * inv * kScale, dir.y() * inv * kScale);
        auto axis = [&](const Vector3f& d) {
          return Vector2f((d.x() * up - dir.x() * d.z()) * inv * inv * kScale,
                          (d.y() * up - dir.y() * d.z()) * inv * inv * kScale);
        };
        // The cloud texture is grey: its luminance is the cover.
        const float cover = scene.clouds().SampleFilteredGray(uv.x(), uv.y(), axis(diff_x[i]), axis(diff_y[i]));
        const float amount = Smoothstep(0.45f, 0.75f, cover) * Smoothstep(0.02f, 0.25f, up);
        c = c * (1.0f - 0.85f * amount) + Vector3f(0.95f, 0.95f, 0.96f) * (0.85f * amount) * (0.9f + 0.2f * cover);
      }
      c *= brightness;
      if (frame.sun_up) {
        const float cosine = dir.dot(frame.sun);
        if (cosine > 0.0f) {
          const float glow = 0.35f * std::pow(cosine, 48.0f) + (cosine > 0.99996f ? 6.0f : 0.0f);
          c += glow * Vector3f(1.0f, 0.95f, 0.85f) * (frame.sun_irradiance / 1.5f);
        }
      }
      colors[i] = c;
      continue;
    }
    const Rigid3d* town_from_object = nullptr;
    const TriangleShading& s = scene.Shading(r.hit.geomID, r.hit.instID[0], r.hit.primID, &town_from_object);
    const Material& material = scene.materials()[s.material];
    const float t = r.ray.tfar;
    const Vector3f p = frame.origin + t * dir;
    Vector3f n = s.normal;
    Vector3f p_obj = p, d_obj = dir, dx_obj = diff_x[i], dy_obj = diff_y[i];
    if (town_from_object) {
      const Eigen::Matrix3f rot = town_from_object->rotation.cast<float>();
      const Vector3f trans = town_from_object->translation.cast<float>();
      n = rot * n;
      p_obj = rot.transpose() * (p - trans);
      d_obj = rot.transpose() * dir;
      dx_obj = rot.transpose() * diff_x[i];
      dy_obj = rot.transpose() * diff_y[i];
    }
    // Two-sided surfaces: the normal faces the viewer.
    float d_dot_n = dir.dot(n);
    if (d_dot_n > 0.0f) {
      n = -n;
      d_dot_n = -d_dot_n;
    }
    d_dot_n = std::min(d_dot_n, -1e-4f);
    const uint64_t object = scene.ObjectKey(r.hit.geomID, r.hit.instID[0]);
    keys[i] = static_cast<uint32_t>(HashMix((object << 32) | static_cast<uint32_t>(s.face))) | 1u;
    if (material.emissive) {
      colors[i] = material.color;
      ambient[i] = -1.0f;
      continue;
    }
    Vector3f a = material.color;
    if (material.texture >= 0) {
      const Texture& texture = scene.textures()[material.texture];
      const Vector3f rel = p_obj - s.p0;
      const float u = s.uv0.x() + s.grad_u.dot(rel);
      const float v = s.uv0.y() + s.grad_v.dot(rel);
      Vector2f axis_a = Vector2f::Zero(), axis_b = Vector2f::Zero();
      if (options_.filter_textures) {
        // Ray differentials (Igehy 1999): dP = t (dD - (dD.n)/(D.n) D), in the object frame.
        const Vector3f n_obj = town_from_object ? Vector3f(town_from_object->rotation.cast<float>().transpose() * n) : n;
        const Vector3f dpx = t * (dx_obj - (dx_obj.dot(n_obj) / d_dot_n) * d_obj);
        const Vector3f dpy = t * (dy_obj - (dy_obj.dot(n_obj) / d_dot_n) * d_obj);
        axis_a = Vector2f(s.grad_u.dot(dpx), s.grad_v.dot(dpx));
        axis_b = Vector2f(s.grad_u.dot(dpy), s.grad_v.dot(dpy));
      }
      if (frame.gray) {
        // Luminance only: lum(tint * texture) ~ lum(tint) * lum(texture) (exact for grey tints).
        const float lum = 0.2126f * a.x() + 0.7152f * a.y() + 0.0722f * a.z();
        a = Vector3f::Constant(lum * (options_.filter_textures ? texture.SampleFilteredGray(u, v, axis_a, axis_b)
                                                               : texture.SampleTrilinearGray(u, v, 0.0f)));
      } else {
        a = a.cwiseProduct(options_.filter_textures ? texture.SampleFiltered(u, v, axis_a, axis_b)
                                                    : texture.SampleTrilinear(u, v, 0.0f));
      }
    }
    albedo[i] = a;
    ambient[i] = frame.sky_irradiance * (0.75f + 0.25f * n.z());
    const float n_dot_l = frame.sun_up ? n.dot(frame.sun) : 0.0f;
    if (n_dot_l > 0.0f) {
      direct[i] = frame.sun_irradiance * n_dot_l;
      if (options_.shadows) {
        RTCRay& sr = shadow[num_shadow];
        const Vector3f o = p + (1e-3f + 1e-4f * t) * n;
        sr.org_x = o.x();
        sr.org_y = o.y();
        sr.org_z = o.z();
        sr.dir_x = frame.sun.x();
        sr.dir_y = frame.sun.y();
        sr.dir_z = frame.sun.z();
        sr.tnear = 0.0f;
        // Above the highest object nothing can cast a shadow: end the ray there (saves most of its traversal).
        sr.tfar = frame.sun.z() > 1e-3f ? std::max(0.0f, (scene.top() - o.z()) / frame.sun.z()) : kInfinity;
        sr.time = 0.0f;
        sr.mask = 0xffffffffu;
        sr.id = i;
        sr.flags = 0;
        shadow_of[num_shadow++] = i;
      }
    }
  }
  if (num_shadow > 0) {
    RTCIntersectContext shadow_context;
    rtcInitIntersectContext(&shadow_context);
    shadow_context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // parallel rays from neighbouring points
    // Rays already occluded by static geometry (tfar = -inf < tnear) are inactive in the second query.
    rtcOccluded1M(scene.static_embree_scene(), &shadow_context, shadow, num_shadow, sizeof(RTCRay));
    if (scene.num_moving_objects() > 0) {
      rtcOccluded1M(scene.moving_embree_scene(), &shadow_context, shadow, num_shadow, sizeof(RTCRay));
    }
    for (int k = 0; k < num_shadow; ++k) {
      if (shadow[k].tfar < 0.0f) {  // occluded: Embree sets tfar to -inf
        const int i = shadow_of[k];
        direct[i] = 0.0f;
        keys[i] ^= 0x80000000u;
      }
    }
  }
  for (int i = 0; i < count; ++i) {
    if (ambient[i] < 0.0f) continue;  // sky or emissive
    colors[i] = albedo[i] * (ambient[i] + direct[i]);
  }
}

void Renderer::RenderTile(const Frame& frame, int tile) const {
  const PixelRay* rays = rays_.data() + tile_begin_[tile];
  const int count = tile_begin_[tile + 1] - tile_begin_[tile];
  Batch& batch = ThreadBatch();
  Vector3f* dirs = batch.dirs;
  Vector3f* dxs = batch.diff_x;
  Vector3f* dys = batch.diff_y;
  Vector3f* colors = batch.colors;
  uint32_t* keys = batch.keys;
  for (int k = 0; k < count; ++k) {
    dirs[k] = frame.rotation * rays[k].bearing;
    dxs[k] = frame.rotation * rays[k].diff_x;
    dys[k] = frame.rotation * rays[k].diff_y;
  }
  TraceBatch(frame, dirs, dxs, dys, count, colors, keys);
  Vector3f* out_color = frame.color;
  uint32_t* out_key = frame.key;
  float* out_level = frame.level;
  const ResponseCurve& response = Response();
  for (int k = 0; k < count; ++k) {
    const int i = rays[k].pixel;
    const Vector3f& c = colors[k];
    out_color[i] = c;
    out_key[i] = keys[k];
    out_level[i] = response(frame.exposure * (0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z()));
  }
}

void Renderer::SupersampleRange(const Frame& frame, const std::vector<int>& pixels, size_t begin,
                                size_t end) const {
  const int ss = options_.antialiasing;
  const int per_pixel = ss * ss;
  const int pixels_per_batch = kBatchSize / per_pixel;
  Batch& batch = ThreadBatch();
  Vector3f* dirs = batch.dirs;
  Vector3f* dxs = batch.diff_x;
  Vector3f* dys = batch.diff_y;
  Vector3f* colors = batch.colors;
  uint32_t* keys = batch.keys;
  Vector3f* out_color = frame.color;
  const float inv_ss = 1.0f / ss;
  for (size_t start = begin; start < end; start += pixels_per_batch) {
    const size_t stop = std::min(end, start + pixels_per_batch);
    int count = 0;
    for (size_t k = start; k < stop; ++k) {
      const int i = pixels[k];
      const PixelRay& ray = rays_[ray_of_pixel_[i]];
      const Vector3f dx = frame.rotation * ray.diff_x * inv_ss;
      const Vector3f dy = frame.rotation * ray.diff_y * inv_ss;
      for (int s = 0; s < per_pixel; ++s) {
        dirs[count] = frame.rotation * sub_bearings_[static_cast<size_t>(i) * per_pixel + s];
        dxs[count] = dx;
        dys[count] = dy;
        ++count;
      }
    }
    TraceBatch(frame, dirs, dxs, dys, count, colors, keys);
    for (size_t k = start; k < stop; ++k) {
      Vector3f sum = Vector3f::Zero();
      for (int s = 0; s < per_pixel; ++s) sum += colors[(k - start) * per_pixel + s];
      out_color[pixels[k]] = sum / static_cast<float>(per_pixel);
    }
  }
}

void Renderer::QuincunxEdges(const Frame& frame, const std::vector<int>& edges) const {
  const int w = frame.width, h = frame.height;
  const int cw = w + 1;
  // The corners of the edge pixels, each traced once even when several edge pixels share it.
  std::vector<uint8_t>& needed = corner_needed_;  // all 0 between frames
  for (const int i : edges) {
    const int c = (i / w) * cw + i % w;
    needed[c] = needed[c + 1] = needed[c + cw] = needed[c + cw + 1] = 1;
  }
  std::vector<int> corners;
  corners.reserve(2 * edges.size() + 16);
  for (size_t c = 0; c < needed.size(); ++c) {
    if (!needed[c]) continue;
    needed[c] = 0;
    if (corner_valid_[c]) corners.push_back(static_cast<int>(c));
  }
  std::vector<Vector3f>& corner_color = corner_color_;  // read only where traced below
  const int batches = static_cast<int>((corners.size() + kBatchSize - 1) / kBatchSize);
  pool_->Run(batches, [&](int b) {
    Batch& batch = ThreadBatch();
    Vector3f* dirs = batch.dirs;
    Vector3f* dxs = batch.diff_x;
    Vector3f* dys = batch.diff_y;
    Vector3f* colors = batch.colors;
    uint32_t* keys = batch.keys;
    const size_t begin = static_cast<size_t>(b) * kBatchSize;
    const int count = static_cast<int>(std::min(corners.size() - begin, static_cast<size_t>(kBatchSize)));
    for (int k = 0; k < count; ++k) {
      const int c = corners[begin + k];
      // Footprint for texture filtering: half the one of the nearest pixel (samples are half a pixel apart).
      const int x = std::min(c % cw, w - 1), y = std::min(c / cw, h - 1);
      const int r = ray_of_pixel_[y * w + x];
      dirs[k] = frame.rotation * corner_bearings_[c];
      dxs[k] = r >= 0 ? Vector3f(frame.rotation * rays_[r].diff_x * 0.5f) : Vector3f::Zero();
      dys[k] = r >= 0 ? Vector3f(frame.rotation * rays_[r].diff_y * 0.5f) : Vector3f::Zero();
    }
    TraceBatch(frame, dirs, dxs, dys, count, colors, keys);
    for (int k = 0; k < count; ++k) corner_color[corners[begin + k]] = colors[k];
  });
  // Quincunx: 1/2 the centre + 1/8 each corner (a tent filter sampled at the centre and the corners; an edge
  // sweeping across the pixel changes it in steps of 1/4, 1/2, 1/4 along the pixel integral's linear ramp).
  Vector3f* out_color = frame.color;
  for (const int i : edges) {
    const int c = (i / w) * cw + i % w;
    Vector3f sum = 4.0f * frame.color[i];
    float weight = 4.0f;
    for (const int k : {c, c + 1, c + cw, c + cw + 1}) {
      if (!corner_valid_[k]) continue;
      sum += corner_color[k];
      weight += 1.0f;
    }
    out_color[i] = sum / weight;
  }
}

cv::Mat Renderer::Render(const Scene& scene, const Rigid3d& town_from_cam, const Lighting& lighting,
                         const SensorOptions& sensor, uint64_t noise_seed) const {
  Frame frame;
  frame.scene = &scene;
  frame.rotation = town_from_cam.rotation.cast<float>();
  frame.origin = town_from_cam.translation.cast<float>();
  frame.sun = lighting.SunDirection().cast<float>();
  frame.sun_up = lighting.sun_elevation_deg > 0.0;
  frame.gray = !sensor.color;
  frame.sun_irradiance = static_cast<float>(lighting.sun_irradiance);
  frame.sky_irradiance = static_cast<float>(lighting.sky_irradiance);
  frame.width = camera_->width();
  frame.height = camera_->height();
  frame.tiles_x = (frame.width + kTileSize - 1) / kTileSize;
  frame.tiles_y = (frame.height + kTileSize - 1) / kTileSize;
  const size_t n = static_cast<size_t>(frame.width) * frame.height;
  frame.exposure = static_cast<float>(sensor.exposure * sensor.gain);
  frame.color = color_.data();
  frame.key = key_.data();
  frame.level = level_.data();
  pool_->Run(frame.tiles_x * frame.tiles_y, [&](int tile) { RenderTile(frame, tile); });

  // Edge pixels: a 4-neighbour sees another object, face or shadow state AND the two differ visibly (by more than
  // options_.edge_contrast grey levels after the sensor response). Low-contrast seams (between the facets of a tree,
  // adjacent walls in the same light) gain nothing from sub-samples.
  std::vector<int> edges;
  if (options_.antialiasing > 1) {
    const int w = frame.width, h = frame.height;
    const float* level = frame.level;
    std::vector<uint8_t>& mark = mark_;  // pixels without a ray stay 0
    const float contrast = static_cast<float>(options_.edge_contrast);
    pool_->Run(h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const int i = y * w + x;
        if (!valid_[i]) continue;
        auto differs = [&](int j) {
          return valid_[j] && frame.key[i] != frame.key[j] && std::abs(level[i] - level[j]) > contrast;
        };
        mark[i] = (x > 0 && differs(i - 1)) || (x + 1 < w && differs(i + 1)) || (y > 0 && differs(i - w)) ||
                  (y + 1 < h && differs(i + w));
      }
    });
    edges.reserve(n / 4);
    for (size_t i = 0; i < n; ++i) {
      if (mark[i]) edges.push_back(static_cast<int>(i));
    }
    if (options_.antialiasing == 2) {
      QuincunxEdges(frame, edges);
    } else {
      constexpr size_t kChunk = 256;
      const int chunks = static_cast<int>((edges.size() + kChunk - 1) / kChunk);
      pool_->Run(chunks, [&](int c) {
        SupersampleRange(frame, edges, c * kChunk, std::min(edges.size(), (c + 1) * kChunk));
      });
    }
  }
  last_supersampled_ = edges.size();

  // Sensor: exposure x gain, gamma response, 8 bits, noise.
  const float scale = static_cast<float>(sensor.exposure * sensor.gain);
  const float sigma = static_cast<float>(sensor.noise_sigma);
  const ResponseCurve& response = Response();
  cv::Mat image(frame.height, frame.width, sensor.color ? CV_8UC3 : CV_8UC1);
  pool_->Run(frame.height, [&](int y) {
    uint8_t* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < frame.width; ++x) {
      const size_t i = static_cast<size_t>(y) * frame.width + x;
      const Vector3f c = frame.color[i] * scale;
      const uint64_t h = HashCombine(noise_seed, i);
      auto quantize = [&](float linear, uint64_t hash) {
        const float value = response(linear) + (sigma > 0.0f ? sigma * HashGaussian(hash) : 0.0f);
        return static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, value)) + 0.5f);
      };
      if (sensor.color) {
        row[3 * x + 0] = quantize(c.z(), HashMix(h + 2));
        row[3 * x + 1] = quantize(c.y(), HashMix(h + 1));
        row[3 * x + 2] = quantize(c.x(), h);
      } else {
        row[x] = quantize(0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z(), h);
      }
    }
  });
  return image;
}

}  // namespace retrace
