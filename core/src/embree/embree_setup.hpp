// Embree 3 set-up shared by the two places that trace the posed triangles: the CPU backend's
// G-buffer pass (backends/cpu/gbuffer_cpu.cpp) and the reference renderer
// (core/src/reference/reference.cpp). One definition of the device and its error channel, the
// triangle geometry of a posed object, the ray and intersect-context initialisation and the
// surface a hit stands for, so that a G-buffer pixel and the reference's un-jittered sample of the
// same pixel see the same surface. Internal (not installed); included by path, and only by those
// two translation units, so that Embree's headers stay there.
#pragma once

#include <embree3/rtcore.h>
#include <sys/types.h>

#include <atomic>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include <glm/glm.hpp>

#include "softgi/scene/scene.hpp"

namespace softgi::embree {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

// Embree reports errors through a callback; the first one is kept and turned into an exception at
// the owner's checkpoints (check). `bytes` tracks what the device holds (vertex/index copies and
// BVHs) when the device was created with track_memory.
struct DeviceState {
  std::mutex m;
  std::string error;
  std::atomic<long long> bytes{0};

  // Throws std::runtime_error "<who>: <what>: <Embree's message>" if an error was reported.
  void check(const char* who, const char* what) {
    std::lock_guard<std::mutex> lock(m);
    if (!error.empty()) throw std::runtime_error(std::string(who) + ": " + what + ": " + error);
  }
  void clear_error() {
    std::lock_guard<std::mutex> lock(m);
    error.clear();
  }
};

inline void device_error(void* user, RTCError code, const char* str) {
  auto* s = static_cast<DeviceState*>(user);
  std::lock_guard<std::mutex> lock(s->m);
  if (s->error.empty()) s->error = "Embree error " + std::to_string(static_cast<int>(code)) + ": " + (str ? str : "");
}
inline bool device_memory(void* user, ssize_t bytes, bool /*post*/) {
  static_cast<DeviceState*>(user)->bytes += static_cast<long long>(bytes);
  return true;
}

// Owning handles, so that an exception thrown half-way through a set-up releases what Embree
// allocated. A device must outlive its scenes and geometries (declare it first).
struct DeviceDeleter {
  void operator()(RTCDevice d) const { rtcReleaseDevice(d); }
};
struct SceneDeleter {
  void operator()(RTCScene s) const { rtcReleaseScene(s); }
};
struct GeometryDeleter {
  void operator()(RTCGeometry g) const { rtcReleaseGeometry(g); }
};
using DeviceHandle = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using SceneHandle = std::unique_ptr<RTCSceneTy, SceneDeleter>;
using GeometryHandle = std::unique_ptr<RTCGeometryTy, GeometryDeleter>;

// A device reporting its errors (and, with track_memory, its allocations) to `state`, which must
// outlive it. Throws std::runtime_error naming `who` when Embree cannot create one.
inline DeviceHandle new_device(DeviceState& state, const char* who, bool track_memory) {
  DeviceHandle d(rtcNewDevice(nullptr));
  if (!d)
    throw std::runtime_error(std::string(who) + ": cannot create the Embree device (error " +
                             std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(d.get(), device_error, &state);
  if (track_memory) rtcSetDeviceMemoryMonitorFunction(d.get(), device_memory, &state);
  return d;
}

// Whether a posed object has anything to trace.
inline bool traced(const scene::PosedObject& o) { return o.source && !o.source->triangles.empty() && !o.positions.empty(); }

// Copies o's posed positions into an Embree FLOAT3 vertex buffer. Throws std::invalid_argument
// naming the mesh and the vertex for a non-finite position (a BVH over it would be meaningless).
inline void copy_vertices(const scene::PosedObject& o, float* vb, const char* who) {
  for (std::size_t v = 0; v < o.positions.size(); ++v) {
    const glm::vec3& p = o.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw std::invalid_argument(std::string(who) + ": mesh '" + o.source->name + "': posed vertex " + std::to_string(v) +
                                  " is not finite");
    vb[3 * v] = p.x;
    vb[3 * v + 1] = p.y;
    vb[3 * v + 2] = p.z;
  }
}

// The committed triangle geometry of posed object o (traced(o) must hold), with `quality` as its
// build quality (RTC_BUILD_QUALITY_REFIT for geometry that moves). Throws std::invalid_argument
// naming the mesh for an out-of-range vertex index or a non-finite vertex, std::runtime_error
// when Embree cannot allocate the buffers; nothing leaks either way.
inline GeometryHandle new_triangle_geometry(RTCDevice device, DeviceState& state, const scene::PosedObject& o, const char* who,
                                            RTCBuildQuality quality = RTC_BUILD_QUALITY_MEDIUM) {
  const auto& tris = o.source->triangles;
  GeometryHandle g(rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE));
  if (!g) {
    state.check(who, "creating a triangle geometry");
    throw std::runtime_error(std::string(who) + ": cannot create an Embree geometry for mesh '" + o.source->name + "'");
  }
  rtcSetGeometryBuildQuality(g.get(), quality);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(g.get(), RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), o.positions.size()));
  auto* ib = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(g.get(), RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tris.size()));
  if (!vb || !ib) {
    state.check(who, "allocating geometry buffers");
    throw std::runtime_error(std::string(who) + ": cannot allocate Embree buffers for mesh '" + o.source->name + "'");
  }
  copy_vertices(o, vb, who);
  for (std::size_t t = 0; t < tris.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      if (tris[t][k] >= o.positions.size())
        throw std::invalid_argument(std::string(who) + ": mesh '" + o.source->name + "': triangle " + std::to_string(t) +
                                    " has vertex index " + std::to_string(tris[t][k]) + " >= " +
                                    std::to_string(o.positions.size()));
      ib[3 * t + k] = tris[t][k];
    }
  rtcCommitGeometry(g.get());
  return g;
}

// A ray from o along d over [tnear, tfar], every field set: all mask bits, time 0, id 0, no flags.
inline RTCRay make_ray(const glm::vec3& o, const glm::vec3& d, float tnear = 0.0f, float tfar = kInf) {
  RTCRay r;
  r.org_x = o.x;
  r.org_y = o.y;
  r.org_z = o.z;
  r.dir_x = d.x;
  r.dir_y = d.y;
  r.dir_z = d.z;
  r.tnear = tnear;
  r.tfar = tfar;
  r.time = 0.0f;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
  return r;
}
// The same ray with its hit record cleared ("no hit" until rtcIntersect says otherwise).
inline RTCRayHit make_ray_hit(const glm::vec3& o, const glm::vec3& d, float tnear = 0.0f, float tfar = kInf) {
  RTCRayHit rh;
  rh.ray = make_ray(o, d, tnear, tfar);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}
inline bool is_hit(const RTCRayHit& rh) { return rh.hit.geomID != RTC_INVALID_GEOMETRY_ID; }
// rtcOccluded1 sets tfar to -inf when the ray is blocked.
inline bool unoccluded(const RTCRay& r) { return r.tfar >= 0.0f; }

// An initialised intersect context; `coherent` for bundles of neighbouring camera rays.
inline void init_context(RTCIntersectContext& ctx, bool coherent = false) {
  rtcInitIntersectContext(&ctx);
  if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
}

// The surface a hit (object, triangle prim, Embree barycentrics u, v) of a ray along dir stands for:
// p = w p0 + u p1 + v p2 (w = 1 - u - v), so that the barycentrics reproduce it exactly; the
// geometric normal turned to face the ray (two-sided surfaces); the interpolated vertex normal,
// normalised and turned to the geometric normal's side, or the geometric normal where vertex
// normals are missing or degenerate.
struct Surface {
  glm::vec3 p{0.0f}, ng{0.0f}, ns{0.0f};
};
// What surface_at needs of the triangle alone, worked out once for every hit on it: its corners,
// vertex normals (null without them) and unit geometric normal (unit_ng false where it is
// degenerate).
struct TriangleSurface {
  const glm::vec3 *p0 = nullptr, *p1 = nullptr, *p2 = nullptr;
  const glm::vec3 *n0 = nullptr, *n1 = nullptr, *n2 = nullptr;
  glm::vec3 ng{0.0f};
  bool unit_ng = false;
};
inline TriangleSurface triangle_surface(const scene::PosedObject& obj, unsigned prim) {
  const glm::uvec3 tri = obj.source->triangles[prim];
  TriangleSurface t;
  t.p0 = &obj.positions[tri.x];
  t.p1 = &obj.positions[tri.y];
  t.p2 = &obj.positions[tri.z];
  if (obj.normals.size() == obj.positions.size()) {
    t.n0 = &obj.normals[tri.x];
    t.n1 = &obj.normals[tri.y];
    t.n2 = &obj.normals[tri.z];
  }
  const glm::vec3 ng = glm::cross(*t.p1 - *t.p0, *t.p2 - *t.p0);
  const float len = glm::length(ng);
  t.unit_ng = len > 0.0f;
  if (t.unit_ng) t.ng = ng / len;
  return t;
}
inline Surface surface_at(const TriangleSurface& t, float u, float v, const glm::vec3& dir) {
  const float w = 1.0f - u - v;
  Surface s;
  s.p = w * *t.p0 + u * *t.p1 + v * *t.p2;
  glm::vec3 ng = t.unit_ng ? t.ng : -dir;
  if (glm::dot(ng, dir) > 0.0f) ng = -ng;
  s.ng = ng;
  s.ns = ng;
  if (t.n0) {
    glm::vec3 n = w * *t.n0 + u * *t.n1 + v * *t.n2;
    const float nl = glm::length(n);
    if (nl > 1e-12f && std::isfinite(nl)) {
      n /= nl;
      s.ns = glm::dot(n, ng) < 0.0f ? -n : n;
    }
  }
  return s;
}
inline Surface surface_at(const scene::PosedObject& obj, unsigned prim, float u, float v, const glm::vec3& dir) {
  return surface_at(triangle_surface(obj, prim), u, v, dir);
}

}  // namespace softgi::embree
