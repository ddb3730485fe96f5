// The CPU implementation of the shared "gbuffer" pass: primary visibility through each pixel centre
// of the shared pinhole camera (softgi/render/camera.hpp), so that pixel (x, y) sees what the
// reference renderer's un-jittered sample of (x, y) sees; and of the shared "receiver_gbuffer" pass
// (paper 000 section 4), the same through every s-th display point. Two ways to find what each
// sample sees, chosen by SOFTGI_CPU_VISIBILITY: "raster" (the default; raster_visibility.cpp, the
// camera rays tested against every triangle over the screen tiles it overlaps) and "embree" (one
// Embree ray per sample, BVH refitted or rebuilt as objects move; 1.2x to 2.8x slower on the
// built-in scenes, bench/README.md).
// Both answer with the same object, triangle and barycentrics up to rounding at shared edges and
// silhouettes, and the surface attributes are resolved from them by one function (resolve_row below,
// its arithmetic in surface_resolve.cpp: the reference renderer's per-hit rule in vector lanes).
// One of the two translation units that include Embree (with the reference renderer; the set-up they
// share, rays, geometry and the surface a hit stands for, is core/src/embree/embree_setup.hpp).
//
// What each plane holds (softgi/render/gbuffer.hpp; the display G-buffer holds the planes the
// frame's passes read, FrameContext::gbuffer_planes, the visibility planes always):
//   position    w p0 + b1 p1 + b2 p2 of the visible triangle (world space), so that the barycentrics
//               reproduce it exactly; 0 for background pixels
//   normal      interpolated vertex normal, normalised, turned to the side of the geometric normal
//               that faces the viewer (two-sided surfaces, the reference renderer's rule); the
//               geometric normal where vertex normals are missing or degenerate; 0 for background
//   depth       eye-space depth (p - e) . E (paper 000 section 4); +inf for background
//   albedo      material albedo * texture(uv) * vertex colour, as in the reference renderer
//   object      PosedScene::objects index (-1 background); primitive: triangle index (-1)
//   barycentric (b1, b2) of vertices 1 and 2 of the triangle; b0 = 1 - b1 - b2
//   view_dir    unit, from the surface towards the eye; the ray direction for background pixels
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "../../core/src/embree/embree_setup.hpp"
#include "../../core/src/render/vertex_image_run.hpp"
#include "raster_visibility.hpp"
#include "surface_resolve.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"

namespace softgi::backends {

namespace {

using glm::vec3;
constexpr int kTile = 16;  // tile edge in pixels: coherent rays per task, enough tasks for both cores

// The Embree scene of the posed objects, kept from frame to frame: when the objects' topology (meshes,
// vertex and triangle counts, indices) is unchanged, only the vertex buffers that moved are
// re-uploaded and their BVHs refitted (static objects cost nothing); otherwise it is rebuilt.
class EmbreeScene {
 public:
  enum class Update { Rebuilt, Refit, Reused };

  // The memory monitor tracks what the device holds (vertex/index copies and the BVHs).
  EmbreeScene() : device_(embree::new_device(state_, "gbuffer", true)) {}
  ~EmbreeScene() { clear(); }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Brings the scene to `posed`. Throws std::invalid_argument naming the mesh for an out-of-range
  // index or a non-finite vertex; after any exception the next update rebuilds.
  Update update(const scene::PosedScene& posed) {
    try {
      Update u = Update::Rebuilt;
      if (scene_ && refits_ < kMaxRefits && same_topology(posed)) {
        u = refit(posed);
      } else {
        rebuild(posed);
      }
      check("building the scene");
      return u;
    } catch (...) {
      clear();
      state_.clear_error();
      throw;
    }
  }

  void check(const char* what) { state_.check("gbuffer", what); }
  RTCScene scene() const { return scene_; }
  int object_of(unsigned geom_id) const { return geom_object_[geom_id]; }
  long long bytes() const { return state_.bytes.load(); }
  long long triangles() const { return triangles_; }

 private:
  // Refitting keeps the tree built for an earlier pose; after this many refits a skinned or
  // far-travelled object gets a fresh build, so tree quality cannot degrade without bound.
  static constexpr int kMaxRefits = 32;

  struct Object {
    int index = -1;  // PosedScene::objects index
    RTCGeometry geom = nullptr;
    std::size_t vertices = 0, triangles = 0;
  };

  void clear() {
    for (auto& o : objects_) rtcReleaseGeometry(o.geom);
    objects_.clear();
    geom_object_.clear();
    if (scene_) rtcReleaseScene(scene_);
    scene_ = nullptr;
    triangles_ = 0;
    refits_ = 0;
  }

  bool same_topology(const scene::PosedScene& posed) const {
    std::size_t k = 0;
    for (std::size_t oi = 0; oi < posed.objects.size(); ++oi) {
      const scene::PosedObject& o = posed.objects[oi];
      if (!embree::traced(o)) continue;
      if (k >= objects_.size()) return false;
      const Object& c = objects_[k++];
      if (c.index != static_cast<int>(oi) || c.vertices != o.positions.size() || c.triangles != o.source->triangles.size())
        return false;
      const void* ib = rtcGetGeometryBufferData(c.geom, RTC_BUFFER_TYPE_INDEX, 0);
      static_assert(sizeof(glm::uvec3) == 3 * sizeof(unsigned));
      if (std::memcmp(ib, o.source->triangles.data(), c.triangles * sizeof(glm::uvec3)) != 0) return false;
    }
    return k == objects_.size();
  }

  Update refit(const scene::PosedScene& posed) {
    bool moved = false;
    for (const Object& c : objects_) {
      const scene::PosedObject& o = posed.objects[c.index];
      auto* vb = static_cast<float*>(rtcGetGeometryBufferData(c.geom, RTC_BUFFER_TYPE_VERTEX, 0));
      static_assert(sizeof(vec3) == 3 * sizeof(float));
      if (std::memcmp(vb, o.positions.data(), c.vertices * sizeof(vec3)) == 0) continue;
      embree::copy_vertices(o, vb, "gbuffer");
      rtcUpdateGeometryBuffer(c.geom, RTC_BUFFER_TYPE_VERTEX, 0);
      rtcCommitGeometry(c.geom);
      moved = true;
    }
    if (!moved) return Update::Reused;
    rtcCommitScene(scene_);
    ++refits_;
    return Update::Refit;
  }

  void rebuild(const scene::PosedScene& posed) {
    clear();
    scene_ = rtcNewScene(device_.get());
    // Dynamic: one BVH per object under a top-level tree, so a moving object refits its own tree
    // only. Low quality (Embree's build for dynamic scenes): on `crowd` (115k triangles) it built
    // about 15% faster than medium quality, with the same trace time for one ray per pixel.
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
    for (std::size_t oi = 0; oi < posed.objects.size(); ++oi)
      if (embree::traced(posed.objects[oi])) add_object(posed.objects[oi], static_cast<int>(oi));
    rtcCommitScene(scene_);
  }

  void add_object(const scene::PosedObject& o, int index) {
    Object c;
    c.index = index;
    c.vertices = o.positions.size();
    c.triangles = o.source->triangles.size();
    // Refit quality: moving objects refit their own BVH (refit()).
    c.geom = embree::new_triangle_geometry(device_.get(), state_, o, "gbuffer", RTC_BUILD_QUALITY_REFIT).release();
    objects_.push_back(c);  // owned from here on: clear() releases it
    const unsigned id = rtcAttachGeometry(scene_, c.geom);
    if (geom_object_.size() <= id) geom_object_.resize(id + 1, -1);
    geom_object_[id] = index;
    triangles_ += static_cast<long long>(c.triangles);
  }

  embree::DeviceState state_;     // outlives the device that reports to it
  embree::DeviceHandle device_;   // released after clear() has released the scene and geometries
  RTCScene scene_ = nullptr;
  std::vector<Object> objects_;
  std::vector<int> geom_object_;
  long long triangles_ = 0;
  int refits_ = 0;
};

// One scene for the process, reused across frames. Created on first use and deliberately never
// destroyed: releasing an Embree device during static destruction races TBB's own teardown. Passes
// that trace it hold the mutex, so concurrent frames take turns in this pass.
std::mutex& cache_mutex() {
  static std::mutex m;
  return m;
}
EmbreeScene& cached_scene() {
  static EmbreeScene* s = new EmbreeScene();
  return *s;
}


enum class Visibility { Raster, Embree };

// SOFTGI_CPU_VISIBILITY, read at every frame so that a benchmark can compare the two in one process.
Visibility visibility_from_environment() {
  const char* env = std::getenv("SOFTGI_CPU_VISIBILITY");
  const std::string v = env ? env : "";
  if (v.empty() || v == "raster") return Visibility::Raster;
  if (v == "embree") return Visibility::Embree;
  throw std::invalid_argument("SOFTGI_CPU_VISIBILITY is '" + v + "'; expected raster or embree");
}

// What finding the visible surfaces of one buffer did, for the pass records.
struct TraceStats {
  Visibility visibility = Visibility::Raster;
  long long rays = 0, hits = 0;
  double update_seconds = 0.0, visibility_seconds = 0.0, resolve_seconds = 0.0;
  EmbreeScene::Update update = EmbreeScene::Update::Reused;
  cpu_raster::RasterStats raster;
};

// Embree: one ray per sample, tiles of coherent rays as streams. Fills object, primitive and
// barycentric of every pixel of gb.
void trace_visibility(render::FrameContext& ctx, const render::PinholeCamera& cam, render::GBuffer& gb, TraceStats& stats) {
  using clock = std::chrono::steady_clock;
  std::lock_guard<std::mutex> lock(cache_mutex());
  const auto t0 = clock::now();
  EmbreeScene& es = cached_scene();
  stats.update = es.update(ctx.posed);
  stats.update_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  const int W = gb.width, H = gb.height;
  const int tiles_x = (W + kTile - 1) / kTile, tiles = tiles_x * ((H + kTile - 1) / kTile);
  std::atomic<long long> hits{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& range) {
    long long local_hits = 0;
    RTCIntersectContext rc;
    embree::init_context(rc, true);  // neighbouring camera rays
    std::array<RTCRayHit, kTile * kTile> rays;
    std::array<std::size_t, kTile * kTile> pixel;
    for (int t = range.begin(); t != range.end(); ++t) {
      const int tx = (t % tiles_x) * kTile, ty = (t / tiles_x) * kTile;
      unsigned m = 0;
      for (int y = ty; y < std::min(H, ty + kTile); ++y)
        for (int x = tx; x < std::min(W, tx + kTile); ++x) {
          pixel[m] = static_cast<std::size_t>(y) * W + x;
          rays[m++] = embree::make_ray_hit(
              cam.position, cam.buffer_direction(x, y, gb.scale));
        }
      // A tile's rays as one coherent stream: Embree packetises them (measured about 15% faster
      // than one rtcIntersect1 per pixel on `spheres` at 512x512).
      rtcIntersect1M(es.scene(), &rc, rays.data(), m, sizeof(RTCRayHit));
      for (unsigned k = 0; k < m; ++k) {
        const RTCRayHit& rh = rays[k];
        const std::size_t i = pixel[k];
        if (!embree::is_hit(rh)) {
          gb.object[i] = gb.primitive[i] = -1;
          continue;
        }
        gb.object[i] = es.object_of(rh.hit.geomID);
        gb.primitive[i] = static_cast<std::int32_t>(rh.hit.primID);
        gb.barycentric[i] = glm::vec2(rh.hit.u, rh.hit.v);
        ++local_hits;
      }
    }
    hits += local_hits;
  });
  es.check("tracing primary rays");
  // The BVH update counts as visibility work, as the rasteriser's set-up does.
  stats.visibility_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  stats.hits = hits.load();
}

// n copies of v: sixteen copies (192 bytes) at a time, which the compiler stores in wide moves
// where a copy of one 12-byte vector at a time takes two narrow stores each.
void fill_vec3(vec3* dst, int n, const vec3& v) {
  std::array<vec3, 16> block;
  block.fill(v);
  int k = 0;
  for (; k + 16 <= n; k += 16) std::memcpy(static_cast<void*>(dst + k), block.data(), sizeof block);
  for (; k < n; ++k) dst[k] = v;
}

// The surface attributes of row y of gb from its visibility planes (object, primitive,
// barycentric): runs of pixels that see one object go through resolve_surface_run (the per-hit rule
// of the reference renderer in vector lanes) and get their albedo per run; runs of misses get
// GBuffer::set_background's values. Only the planes gb holds are written.
void resolve_row(const scene::Scene& sc, const scene::PosedScene& posed, const render::PinholeCamera& cam,
                 const render::BufferRays& rays, int y, render::GBuffer& gb) {
  const int W = gb.width;
  const std::size_t row0 = static_cast<std::size_t>(y) * W;
  const bool surface = (gb.planes & render::kGBufferSurface) != 0, albedo = (gb.planes & render::kGBufferAlbedo) != 0,
             view_dir = (gb.planes & render::kGBufferViewDir) != 0;
  for (int x = 0; x < W;) {
    const std::size_t i = row0 + x;
    const int oi = gb.object[i];
    const int x1 = render::object_run_end(&gb.object[row0], x, W);
    const int n = x1 - x;
    if (oi < 0) {
      // A run of misses: GBuffer::set_background's values, one plane at a time; zeros and -1 as
      // bytes (0.0f is all zero bits, -1 all one bits).
      const auto zero = [&](auto& plane) { std::memset(static_cast<void*>(&plane[i]), 0, n * sizeof(plane[i])); };
      if (surface) {
        zero(gb.position);
        zero(gb.normal);
        std::fill_n(&gb.depth[i], n, std::numeric_limits<float>::infinity());
      }
      if (albedo) zero(gb.albedo);
      if (view_dir)
        render::detail::ray_directions(cam.forward, cam.right, cam.up, &rays.sx[x], rays.sy[static_cast<std::size_t>(y)], n, &gb.view_dir[i]);
      std::memset(static_cast<void*>(&gb.primitive[i]), 0xff, n * sizeof(std::int32_t));
      zero(gb.barycentric);
      x = x1;
      continue;
    }
    const scene::PosedObject& obj = posed.objects[oi];
    if (surface) {
      const cpu_resolve::ObjectArrays arrays{obj.source->triangles.data(), obj.positions.data(),
                                             obj.normals.size() == obj.positions.size() ? obj.normals.data() : nullptr};
      cpu_resolve::resolve_surface_run(cam, arrays, &gb.primitive[i], &gb.barycentric[i], &rays.sx[x],
                                       rays.sy[static_cast<std::size_t>(y)], n, &gb.position[i], &gb.normal[i],
                                       &gb.depth[i], view_dir ? &gb.view_dir[i] : nullptr);
    } else if (view_dir) {
      render::detail::ray_directions(cam.forward, cam.right, cam.up, &rays.sx[x], rays.sy[static_cast<std::size_t>(y)], n, &gb.view_dir[i]);
      for (int k = 0; k < n; ++k) gb.view_dir[i + k] = -gb.view_dir[i + k];
    }
    if (albedo) {
      vec3 a(0.0f);
      if (scene::constant_albedo(sc, obj, a)) {
        fill_vec3(&gb.albedo[i], n, a);
      } else {
        for (int k = 0; k < n; ++k)
          gb.albedo[i + k] = scene::surface_albedo(sc, obj, static_cast<std::size_t>(gb.primitive[i + k]),
                                                   gb.barycentric[i + k].x, gb.barycentric[i + k].y);
      }
    }
    x = x1;
  }
}

// The one primary-visibility loop of the CPU backend: a buffer of ceil(W/s) x ceil(H/s) pixels whose
// pixel (x, y) holds the hit of the display camera's ray through display point ((x + 0.5) s,
// (y + 0.5) s). s = 1 is the display G-buffer; s > 1 the receiver buffer of paper 000 section 4, whose
// samples then lie exactly on display points, so that upsampling can place them (gbuffer.hpp).
render::GBuffer trace_buffer(render::FrameContext& ctx, int scale, unsigned planes, const char* who, TraceStats& stats) {
  using clock = std::chrono::steady_clock;
  const render::PinholeCamera cam = render::make_pinhole_camera(ctx.scene, ctx.width, ctx.height, who);
  stats.visibility = visibility_from_environment();
  const int W = (ctx.width + scale - 1) / scale, H = (ctx.height + scale - 1) / scale;
  // Every pixel is written below (a hit by resolve_row, a miss by set_background), in last frame's
  // buffers. Two phases, timed apart: visibility finds each pixel's object, triangle and
  // barycentrics (a visibility buffer); the resolve derives the surface attributes from them.
  render::GBuffer gb = render::GBuffer::for_overwrite(W, H, scale, ctx.pool(), planes);
  if (stats.visibility == Visibility::Embree) {
    trace_visibility(ctx, cam, gb, stats);
  } else {
    cpu_raster::rasterise_visibility(cam, ctx.posed, who, gb, stats.raster, ctx.id());
    stats.visibility_seconds = stats.raster.setup_seconds + stats.raster.raster_seconds;
    stats.hits = stats.raster.hits;
  }
  const render::BufferRays rays(cam, W, H, scale);  // cam.buffer_direction and buffer_ray, per column and row
  const auto t2 = clock::now();
  tbb::parallel_for(tbb::blocked_range<int>(0, H, 4), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y) resolve_row(ctx.scene, ctx.posed, cam, rays, y, gb);
  });
  stats.resolve_seconds = std::chrono::duration<double>(clock::now() - t2).count();
  stats.rays = static_cast<long long>(W) * H;
  return gb;
}

void trace_counters(render::PassRecord& rec, const TraceStats& st) {
  rec.counters["rays"] = static_cast<double>(st.rays);
  rec.counters["hits"] = static_cast<double>(st.hits);
  rec.counters["visibility_seconds"] = st.visibility_seconds;
  rec.counters["resolve_seconds"] = st.resolve_seconds;
  rec.counters["raster"] = st.visibility == Visibility::Raster ? 1.0 : 0.0;
  if (st.visibility == Visibility::Raster) {
    rec.counters["triangles"] = static_cast<double>(st.raster.triangles);
    rec.counters["triangles_set_up"] = static_cast<double>(st.raster.set_up);
    rec.counters["tile_entries"] = static_cast<double>(st.raster.tile_entries);
    rec.counters["raster_setup_seconds"] = st.raster.setup_seconds;
    rec.counters["raster_setup_reused"] = st.raster.reused ? 1.0 : 0.0;
    return;
  }
  const EmbreeScene& es = cached_scene();
  rec.counters["triangles"] = static_cast<double>(es.triangles());
  rec.counters["bvh_update_seconds"] = st.update_seconds;
  rec.counters["bvh_rebuilt"] = st.update == EmbreeScene::Update::Rebuilt ? 1.0 : 0.0;
  rec.counters["bvh_refit"] = st.update == EmbreeScene::Update::Refit ? 1.0 : 0.0;
  rec.counters["embree_bytes"] = static_cast<double>(es.bytes());
}

// The "gbuffer" and "receiver_gbuffer" renderer. Paper 000 section 4, receiver setup: the receiver
// buffer at 1/s of the display resolution per axis; at s = 1 it is the display G-buffer itself,
// copied when the frame has one (render::run_receiver_gbuffer_pass: no second trace). Held: what
// the visibility method keeps for the next frame (the rasteriser's working memory; Embree's geometry
// copies and BVHs).
render::GBuffer produce_gbuffer(render::FrameContext& ctx, int s, const char* pass, std::size_t& held) {
  TraceStats st;
  // The display G-buffer holds the planes the frame's passes read; a receiver buffer holds all.
  const unsigned planes = s == 1 && std::string(pass) == "gbuffer" ? ctx.gbuffer_planes() : render::kGBufferAll;
  render::GBuffer gb = trace_buffer(ctx, s, planes, pass, st);
  trace_counters(ctx.record(), st);
  // For the benchmarks' bandwidth shares: every plane written once.
  ctx.record().counters["bytes_moved"] = static_cast<double>(gb.bytes());
  held = st.visibility == Visibility::Embree ? static_cast<std::size_t>(std::max(0LL, cached_scene().bytes()))
                                             : st.raster.held_bytes;
  return gb;
}

}  // namespace

std::size_t cpu_resolve::surface_resolve_differences(const render::PinholeCamera& cam, const scene::Scene& sc,
                                                     const scene::PosedScene& posed, const render::GBuffer& gb) {
  const render::BufferRays rays(cam, gb.width, gb.height, gb.scale);
  const bool surface = gb.has(render::kGBufferSurface), albedo = gb.has(render::kGBufferAlbedo),
             view_dir = gb.has(render::kGBufferViewDir);
  const auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof(a)) == 0; };
  std::size_t differ = 0;
  for (int y = 0; y < gb.height; ++y)
    for (int x = 0; x < gb.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * gb.width + x;
      const int oi = gb.object[i];
      if (oi < 0) {
        // What GBuffer::set_background writes for this pixel's ray.
        render::GBuffer bg = render::GBuffer::background(1, 1, 1, nullptr, gb.planes);
        bg.set_background(0, view_dir ? rays.direction(x, y) : vec3(0.0f));
        bool ok = same(gb.primitive[i], bg.primitive[0]) && same(gb.barycentric[i], bg.barycentric[0]);
        if (surface) ok = ok && same(gb.position[i], bg.position[0]) && same(gb.normal[i], bg.normal[0]) && same(gb.depth[i], bg.depth[0]);
        if (albedo) ok = ok && same(gb.albedo[i], bg.albedo[0]);
        if (view_dir) ok = ok && same(gb.view_dir[i], bg.view_dir[0]);
        differ += ok ? 0 : 1;
        continue;
      }
      const scene::PosedObject& obj = posed.objects[oi];
      const unsigned prim = static_cast<unsigned>(gb.primitive[i]);
      const float u = gb.barycentric[i].x, v = gb.barycentric[i].y;
      // The reference renderer's rule, one hit at a time (embree_setup.hpp), with the ray as the
      // resolve takes it: unit where it is written as view_dir or stands in for a degenerate normal.
      const embree::TriangleSurface tri = embree::triangle_surface(obj, prim);
      const vec3 dir = view_dir || !tri.unit_ng ? rays.direction(x, y) : rays.ray(x, y);
      const embree::Surface sf = embree::surface_at(tri, u, v, dir);
      bool ok = true;
      if (surface) ok = ok && same(gb.position[i], sf.p) && same(gb.normal[i], sf.ns) && same(gb.depth[i], cam.depth(sf.p));
      if (albedo) ok = ok && same(gb.albedo[i], scene::surface_albedo(sc, obj, prim, u, v));
      if (view_dir) ok = ok && same(gb.view_dir[i], -dir);
      differ += ok ? 0 : 1;
    }
  return differ;
}

void register_cpu_shared_passes() { render::register_gbuffer_pass_impls(cpu::kBackendName, produce_gbuffer); }

}  // namespace softgi::backends
