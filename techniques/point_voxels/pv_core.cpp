// Point-proxy voxels: proxies, voxels, marching, the visibility filter, gathering and the lights'
// depth maps (paper 002, Chen et al. 2014, sections 3.1-3.3).
#include "pv_core.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "softgi/render/frame_pool.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace softgi::techniques::point_voxels {

namespace {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInf = std::numeric_limits<float>::infinity();

std::uint32_t float_bits(float f) {
  if (f == 0.0f) f = 0.0f;  // -0 and +0 hash alike
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

double to_unit(std::uint64_t h) { return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0); }

std::uint64_t position_hash(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 m = (a + b + c) / 3.0f;
  std::uint64_t h = 0x9e3779b97f4a7c15ULL;
  for (float f : {m.x, m.y, m.z}) h = mix_hash(h ^ float_bits(f));
  return h;
}

// The order-2 real SH basis (l <= 1) at unit w; projection and reconstruction both use it, so only
// its orthonormality matters.
std::array<float, 4> basis2(const glm::vec3& w) {
  constexpr float y0 = 0.28209479177387814f, y1 = 0.4886025119029199f;
  return {y0, y1 * w.y, y1 * w.z, y1 * w.x};
}

}  // namespace

std::uint64_t mix_hash(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

double radical_inverse(std::uint32_t i, std::uint32_t base) {
  double inv = 1.0 / base, f = inv, r = 0.0;
  while (i > 0) {
    r += f * (i % base);
    i /= base;
    f *= inv;
  }
  return r;
}

double position_hash01(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) { return to_unit(position_hash(a, b, c)); }

ProxySampling sample_point_proxies(const scene::PosedScene& geometry, double target_count) {
  if (!(target_count > 0.0) || !std::isfinite(target_count))
    throw std::invalid_argument("point proxies: target count " + std::to_string(target_count) + " must be positive and finite");
  ProxySampling out;
  for (const auto& obj : geometry.objects) {
    for (const auto& t : obj.source->triangles) {
      const double a = 0.5 * glm::length(glm::cross(obj.positions[t.y] - obj.positions[t.x], obj.positions[t.z] - obj.positions[t.x]));
      if (std::isfinite(a)) out.total_area += a;
    }
  }
  if (!(out.total_area > 0.0)) throw std::invalid_argument("point proxies: the scene has no triangle of positive area to sample");
  out.density = target_count / out.total_area;
  out.samples.reserve(static_cast<std::size_t>(target_count * 1.01) + 16);
  for (std::size_t o = 0; o < geometry.objects.size(); ++o) {
    const auto& obj = geometry.objects[o];
    const auto& tris = obj.source->triangles;
    for (std::size_t k = 0; k < tris.size(); ++k) {
      const glm::vec3 &a = obj.positions[tris[k].x], &b = obj.positions[tris[k].y], &c = obj.positions[tris[k].z];
      const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
      if (!(area > 0.0) || !std::isfinite(area)) continue;
      const double n = area * out.density;
      const std::uint64_t h = position_hash(a, b, c);
      double whole = std::floor(n);
      const double frac = n - whole;
      if (frac > 0.0) {
        ++out.roulette_triangles;
        // Russian roulette (section 3.1): one more proxy when the triangle's hash is below frac(n).
        if (to_unit(h) < frac) whole += 1.0;
      }
      const auto count = static_cast<std::uint32_t>(whole);
      // Cranley-Patterson rotation of the Halton points per triangle, so that neighbouring
      // triangles' samples do not line up.
      const double r1 = to_unit(mix_hash(h + 1)), r2 = to_unit(mix_hash(h + 2));
      for (std::uint32_t j = 0; j < count; ++j) {
        double u = radical_inverse(j + 1, 2) + r1, v = radical_inverse(j + 1, 3) + r2;
        u -= std::floor(u);
        v -= std::floor(v);
        const double su = std::sqrt(u);
        ProxySample s;
        s.object = static_cast<std::int32_t>(o);
        s.prim = static_cast<std::int32_t>(k);
        s.b1 = static_cast<float>(su * (1.0 - v));
        s.b2 = static_cast<float>(su * v);
        out.samples.push_back(s);
      }
    }
  }
  return out;
}

PosedProxies pose_proxies(const scene::Scene& scene, const scene::PosedScene& posed, const ProxySampling& s,
                          double disc_scale) {
  PosedProxies p;
  const std::size_t n = s.samples.size();
  p.position.resize(n);
  p.normal.resize(n);
  p.albedo.resize(n);
  p.radiance.assign(n, glm::vec3(0.0f));
  p.radius = static_cast<float>(disc_scale / std::sqrt(static_cast<double>(kPi) * s.density));
  p.patch_area = static_cast<float>(1.0 / s.density);
  for (std::size_t i = 0; i < n; ++i) {
    const ProxySample& q = s.samples[i];
    const auto& obj = posed.objects.at(static_cast<std::size_t>(q.object));
    const glm::uvec3 t = obj.source->triangles.at(static_cast<std::size_t>(q.prim));
    const float b0 = 1.0f - q.b1 - q.b2;
    p.position[i] = b0 * obj.positions[t.x] + q.b1 * obj.positions[t.y] + q.b2 * obj.positions[t.z];
    glm::vec3 nn = b0 * obj.normals[t.x] + q.b1 * obj.normals[t.y] + q.b2 * obj.normals[t.z];
    const float len = glm::length(nn);
    if (!(len > 1e-12f)) {
      nn = glm::cross(obj.positions[t.y] - obj.positions[t.x], obj.positions[t.z] - obj.positions[t.x]);
      const float gl = glm::length(nn);
      nn = gl > 0.0f ? nn / gl : glm::vec3(0.0f, 1.0f, 0.0f);
    } else {
      nn /= len;
    }
    p.normal[i] = nn;
    p.albedo[i] = scene::surface_albedo(scene, obj, static_cast<std::size_t>(q.prim), q.b1, q.b2);
  }
  return p;
}

glm::ivec3 VoxelGrid::cell_of(const glm::vec3& p) const {
  glm::ivec3 v(glm::floor((p - lo) * inv_cell));
  return glm::clamp(v, glm::ivec3(0), dims - 1);
}

std::size_t VoxelGrid::bytes() const {
  return start.size() * sizeof(std::uint32_t) + key.size() * sizeof(std::uint32_t) + centroid.size() * sizeof(glm::vec3) +
         sh.size() * sizeof(sh[0]);
}

VoxelGrid grid_frame(const PosedProxies& proxies, glm::ivec3 dims) {
  if (dims.x < 1 || dims.y < 1 || dims.z < 1 || static_cast<double>(dims.x) * dims.y * dims.z > 1 << 24)
    throw std::invalid_argument("voxel grid: " + std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" +
                                std::to_string(dims.z) + " cells (expected 1 to 2^24 cells)");
  VoxelGrid g;
  g.dims = dims;
  glm::vec3 lo(kInf), hi(-kInf);
  for (const auto& p : proxies.position) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  if (proxies.size() == 0) lo = hi = glm::vec3(0.0f);
  const glm::vec3 pad(std::max(proxies.radius, 1e-4f));
  g.lo = lo - pad;
  g.cell = glm::max((hi + pad - g.lo) / glm::vec3(dims), glm::vec3(1e-6f));
  g.inv_cell = 1.0f / g.cell;
  return g;
}

VoxelGrid build_voxel_grid(PosedProxies& proxies, glm::ivec3 dims, std::vector<std::uint32_t>* permutation) {
  VoxelGrid g = grid_frame(proxies, dims);
  const std::size_t n = proxies.size();
  std::vector<std::uint32_t> keys(n), order(n);
  for (std::size_t i = 0; i < n; ++i) keys[i] = g.hash(g.cell_of(proxies.position[i]));
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
  auto permute = [&](std::vector<glm::vec3>& v) {
    std::vector<glm::vec3> out(n);
    for (std::size_t i = 0; i < n; ++i) out[i] = v[order[i]];
    v.swap(out);
  };
  permute(proxies.position);
  permute(proxies.normal);
  permute(proxies.albedo);
  permute(proxies.radiance);
  g.key.resize(n);
  for (std::size_t i = 0; i < n; ++i) g.key[i] = keys[order[i]];
  g.start.assign(g.cells() + 1, 0);
  for (std::uint32_t k : g.key) ++g.start[k + 1];
  for (std::size_t k = 0; k < g.cells(); ++k) g.start[k + 1] += g.start[k];
  if (permutation) *permutation = std::move(order);
  return g;
}

void accumulate_voxel_sh(VoxelGrid& grid, const PosedProxies& proxies) {
  const std::size_t cells = grid.cells();
  grid.centroid.assign(cells, glm::vec3(0.0f));
  grid.sh.assign(cells, {glm::vec3(0.0f), glm::vec3(0.0f), glm::vec3(0.0f), glm::vec3(0.0f)});
  // ZH of max(0, cos) times sqrt(4 pi / (2l + 1)): pi for l = 0, 2 pi / 3 for l = 1.
  constexpr float k0 = kPi, k1 = 2.0f * kPi / 3.0f;
  const float area = proxies.patch_area;
  for (std::size_t k = 0; k < cells; ++k) {
    const std::uint32_t b = grid.start[k], e = grid.start[k + 1];
    if (b == e) continue;
    glm::vec3 c(0.0f);
    auto& s = grid.sh[k];
    for (std::uint32_t i = b; i < e; ++i) {
      c += proxies.position[i];
      const auto y = basis2(proxies.normal[i]);
      const glm::vec3 la = proxies.radiance[i] * area;
      s[0] += la * (k0 * y[0]);
      for (int m = 1; m < 4; ++m) s[m] += la * (k1 * y[m]);
    }
    grid.centroid[k] = c / static_cast<float>(e - b);
  }
}

float ray_disc(const glm::vec3& o, const glm::vec3& d, const glm::vec3& c, const glm::vec3& n, float r) {
  const float dn = glm::dot(d, n);
  if (std::abs(dn) < 1e-8f) return -1.0f;
  const float t = glm::dot(c - o, n) / dn;
  if (!(t >= 0.0f)) return -1.0f;
  const glm::vec3 q = o + t * d - c;
  return glm::dot(q, q) <= r * r ? t : -1.0f;
}

namespace {

// Whether o + t d, t in [t_min, t_max], hits any of the discs [b, e) of `v` (radius r): ray_disc's
// arithmetic, operation for operation, kProxyLanes discs at a time (lanes past e count no hit).
// Compiled for several instruction sets; -ffp-contract=off for this file keeps every version's
// bits those of the baseline, so each disc's answer is ray_disc's.
__attribute__((target_clones("avx512f", "avx2", "default"))) bool any_disc_hit(const ProxyPlanes& v, std::uint32_t b,
                                                                               std::uint32_t e, glm::vec3 o, glm::vec3 d, float r,
                                                                               float t_min, float t_max) {
  const float *px = v.px.data(), *py = v.py.data(), *pz = v.pz.data();
  const float *nx = v.nx.data(), *ny = v.ny.data(), *nz = v.nz.data();
  const float r2 = r * r;
  for (std::uint32_t i = b; i < e; i += kProxyLanes) {
    const int left = static_cast<int>(e - i);
    int hits = 0;
    for (std::size_t l = 0; l < kProxyLanes; ++l) {
      const std::size_t j = i + l;
      const float dn = d.x * nx[j] + d.y * ny[j] + d.z * nz[j];
      const float t = ((px[j] - o.x) * nx[j] + (py[j] - o.y) * ny[j] + (pz[j] - o.z) * nz[j]) / dn;
      const float qx = (o.x + t * d.x) - px[j], qy = (o.y + t * d.y) - py[j], qz = (o.z + t * d.z) - pz[j];
      const bool hit = (static_cast<int>(l) < left) & !(std::abs(dn) < 1e-8f) & (t >= 0.0f) & (qx * qx + qy * qy + qz * qz <= r2) &
                       (t >= t_min) & (t <= t_max);
      hits += hit ? 1 : 0;
    }
    if (hits > 0) return true;
  }
  return false;
}

}  // namespace

glm::vec3 cosine_direction(const glm::vec3& n, float u, float v) {
  const float a = 2.0f * u - 1.0f, b = 2.0f * v - 1.0f;
  float r, phi;
  if (a == 0.0f && b == 0.0f) {
    r = 0.0f;
    phi = 0.0f;
  } else if (std::abs(a) > std::abs(b)) {
    r = a;
    phi = (kPi / 4.0f) * (b / a);
  } else {
    r = b;
    phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b);
  }
  const float x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0f, 1.0f - x * x - y * y));
  const glm::vec3 t = std::abs(n.x) > 0.9f ? glm::vec3(0.0f, 1.0f, 0.0f) : glm::vec3(1.0f, 0.0f, 0.0f);
  const glm::vec3 tu = glm::normalize(glm::cross(t, n)), tv = glm::cross(n, tu);
  return glm::normalize(x * tu + y * tv + z * n);
}

std::int32_t march_ray(const VoxelGrid& grid, const PosedProxies& proxies, const glm::vec3& o, const glm::vec3& d,
                       float t_min, float t_max, const ProxyPlanes* planes, MarchCount* count) {
  if (grid.key.empty()) return -1;
  if (planes != nullptr && planes->size != proxies.size())
    throw std::invalid_argument("march_ray: proxy planes of " + std::to_string(planes->size) + " proxies for " +
                                std::to_string(proxies.size()));
  const glm::vec3 hi = grid.lo + grid.cell * glm::vec3(grid.dims);
  float t0 = t_min, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12f) {
      if (o[a] < grid.lo[a] || o[a] > hi[a]) return -1;
      continue;
    }
    float ta = (grid.lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 <= t1)) return -1;
  glm::ivec3 v = grid.cell_of(o + d * t0);
  glm::ivec3 step;
  glm::vec3 t_next, t_delta;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12f) {
      step[a] = 0;
      t_next[a] = kInf;
      t_delta[a] = kInf;
      continue;
    }
    step[a] = d[a] > 0.0f ? 1 : -1;
    const float boundary = grid.lo[a] + static_cast<float>(v[a] + (step[a] > 0 ? 1 : 0)) * grid.cell[a];
    t_next[a] = (boundary - o[a]) / d[a];
    t_delta[a] = grid.cell[a] / std::abs(d[a]);
  }
  const float r = proxies.radius;
  for (;;) {
    const std::uint32_t k = grid.hash(v);
    if (count != nullptr) {
      ++count->cells;
      count->discs += grid.start[k + 1] - grid.start[k];
    }
    if (planes != nullptr) {
      if (any_disc_hit(*planes, grid.start[k], grid.start[k + 1], o, d, r, t_min, t_max)) return static_cast<std::int32_t>(k);
    } else {
      for (std::uint32_t i = grid.start[k]; i < grid.start[k + 1]; ++i) {
        const float t = ray_disc(o, d, proxies.position[i], proxies.normal[i], r);
        if (t >= t_min && t <= t_max) return static_cast<std::int32_t>(k);
      }
    }
    int a = 0;
    if (t_next[1] < t_next[a]) a = 1;
    if (t_next[2] < t_next[a]) a = 2;
    if (t_next[a] > t1) return -1;
    v[a] += step[a];
    if (v[a] < 0 || v[a] >= grid.dims[a]) return -1;
    t_next[a] += t_delta[a];
  }
}

namespace {

// Delta_d delta_n of eq. 4.
bool same_surface(float zp, float zq, const glm::vec3& np, const glm::vec3& nq, const FilterOptions& opt) {
  if (!std::isfinite(zq)) return false;
  // In float, as the GPU's filter compares.
  return std::abs(zq - zp) <= static_cast<float>(opt.depth_threshold) * zp && glm::dot(np, nq) >= static_cast<float>(opt.normal_threshold);
}

void check_filter(const FilterOptions& opt) {
  if (opt.radius_x < 0 || opt.radius_y < 0 || opt.radius_x > 64 || opt.radius_y > 64)
    throw std::invalid_argument("visibility filter: radius " + std::to_string(opt.radius_x) + "x" + std::to_string(opt.radius_y) +
                                " (expected 0 to 64)");
}

}  // namespace

PixelLists visibility_filter(const PixelLists& in, const float* depth, const glm::vec3* normal, const FilterOptions& opt) {
  check_filter(opt);
  if (in.width < 0 || in.height < 0) throw std::invalid_argument("visibility filter: negative list size");
  const std::size_t np = static_cast<std::size_t>(in.width) * in.height;
  if (in.offset.size() != np + 1 || in.offset.front() != 0 || in.offset.back() != in.voxel.size())
    throw std::invalid_argument("visibility filter: " + std::to_string(in.offset.size()) + " list offsets ending at " +
                                (in.offset.empty() ? std::string("nothing") : std::to_string(in.offset.back())) + " for " +
                                std::to_string(in.width) + "x" + std::to_string(in.height) + " pixels and " +
                                std::to_string(in.voxel.size()) + " voxel entries");
  std::int32_t top = -1;
  for (const std::int32_t v : in.voxel) {
    if (v < 0) throw std::invalid_argument("visibility filter: negative voxel index " + std::to_string(v) + " in a list");
    top = std::max(top, v);
  }
  PixelLists out;
  out.width = in.width;
  out.height = in.height;
  out.offset.assign(np + 1, 0);
  // A window's lists overlap heavily (neighbours see the same voxels): each voxel is kept the first
  // time it is met, marked with the pixel that took it, and only the union is sorted. Voxel indices
  // beyond kMaxMarks (no grid of the technique has so many) fall back to sorting every entry.
  constexpr std::int32_t kMaxMarks = 1 << 24;
  const bool marked = top < kMaxMarks;
  tbb::enumerable_thread_specific<std::vector<std::uint32_t>> marks(
      [&] { return std::vector<std::uint32_t>(marked ? static_cast<std::size_t>(top) + 1 : 0, 0u); });
  // Rows run in parallel into lists of their own, laid end to end afterwards.
  std::vector<std::vector<std::int32_t>> rows(static_cast<std::size_t>(in.height));
  tbb::parallel_for(tbb::blocked_range<int>(0, in.height), [&](const tbb::blocked_range<int>& range) {
    std::vector<std::uint32_t>& mark = marks.local();
    for (int y = range.begin(); y != range.end(); ++y) {
      std::vector<std::int32_t>& row = rows[static_cast<std::size_t>(y)];
      for (int x = 0; x < in.width; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * in.width + x;
        const std::size_t first = row.size();
        const float zp = depth[p];
        if (std::isfinite(zp)) {
          const auto stamp = static_cast<std::uint32_t>(p + 1);
          for (int j = std::max(0, y - opt.radius_y); j <= std::min(in.height - 1, y + opt.radius_y); ++j)
            for (int i = std::max(0, x - opt.radius_x); i <= std::min(in.width - 1, x + opt.radius_x); ++i) {
              const std::size_t q = static_cast<std::size_t>(j) * in.width + i;
              if (q != p && !same_surface(zp, depth[q], normal[p], normal[q], opt)) continue;
              for (std::uint32_t e = in.offset[q]; e < in.offset[q + 1]; ++e) {
                const std::int32_t v = in.voxel[e];
                if (!marked) {
                  row.push_back(v);
                } else if (mark[static_cast<std::size_t>(v)] != stamp) {
                  mark[static_cast<std::size_t>(v)] = stamp;
                  row.push_back(v);
                }
              }
            }
          std::sort(row.begin() + static_cast<std::ptrdiff_t>(first), row.end());
          if (!marked) row.erase(std::unique(row.begin() + static_cast<std::ptrdiff_t>(first), row.end()), row.end());
        }
        out.offset[p + 1] = static_cast<std::uint32_t>(row.size() - first);
      }
    }
  });
  std::size_t total = 0;
  for (std::size_t p = 0; p < np; ++p) {
    total += out.offset[p + 1];
    if (total > std::numeric_limits<std::uint32_t>::max())
      throw std::invalid_argument("visibility filter: the filtered lists exceed 2^32 entries");
    out.offset[p + 1] = static_cast<std::uint32_t>(total);
  }
  out.voxel.resize(total);
  tbb::parallel_for(tbb::blocked_range<int>(0, in.height), [&](const tbb::blocked_range<int>& range) {
    for (int y = range.begin(); y != range.end(); ++y) {
      const std::vector<std::int32_t>& row = rows[static_cast<std::size_t>(y)];
      std::copy(row.begin(), row.end(), out.voxel.begin() + out.offset[static_cast<std::size_t>(y) * in.width]);
    }
  });
  return out;
}

void filter_field(const float* in, int channels, int width, int height, const float* depth, const glm::vec3* normal,
                  const FilterOptions& opt, float* out) {
  check_filter(opt);
  const auto c = static_cast<std::size_t>(channels);
  // Each pixel writes only its own output: rows run in parallel.
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& range) {
    for (int y = range.begin(); y != range.end(); ++y)
      for (int x = 0; x < width; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * width + x;
        for (std::size_t k = 0; k < c; ++k) out[p * c + k] = 0.0f;
        if (!std::isfinite(depth[p])) continue;
        int n = 0;
        for (int j = std::max(0, y - opt.radius_y); j <= std::min(height - 1, y + opt.radius_y); ++j)
          for (int i = std::max(0, x - opt.radius_x); i <= std::min(width - 1, x + opt.radius_x); ++i) {
            const std::size_t q = static_cast<std::size_t>(j) * width + i;
            if (q != p && !same_surface(depth[p], depth[q], normal[p], normal[q], opt)) continue;
            for (std::size_t k = 0; k < c; ++k) out[p * c + k] += in[q * c + k];
            ++n;
          }
        for (std::size_t k = 0; k < c; ++k) out[p * c + k] /= static_cast<float>(n);
      }
  });
}

float eq7_weight(float cos_theta, float ns, float sigma) {
  const float x = std::abs(1.0f - std::pow(std::max(0.0f, cos_theta), ns)) / sigma;
  return std::exp(-0.5f * x * x) / (sigma * std::sqrt(2.0f * kPi));
}

float eq7_sigma(float ns, float scale) { return scale * std::sqrt(2.0f / (ns + 2.0f)); }

float glossy_lobe(const Receiver& r, const glm::vec3& w) {
  if (!(r.glossy > 0.0f)) return 0.0f;
  const float ca = glm::dot(r.reflect, w);
  return ca > 0.0f ? r.glossy * (r.ns + 2.0f) / (2.0f * kPi) * std::pow(ca, r.ns) : 0.0f;
}

namespace {

// One light's glossy term (E times the normalised lobe), and eq. 7's sums.
inline void add_glossy(const Receiver& r, const glm::vec3& e, const glm::vec3& wn, float lobe_norm, float weight, Gathered& out) {
  const float ca = glm::dot(r.reflect, wn);
  if (ca <= 0.0f) return;
  const glm::vec3 g = e * (lobe_norm * std::pow(ca, r.ns));
  out.glossy += weight * g;
  if (r.eq7_sigma > 0.0f) {
    // w / w_max = the Gaussian without its normalisation: 1 at the reflection vector.
    const float rel = eq7_weight(ca, r.ns, r.eq7_sigma) * (r.eq7_sigma * std::sqrt(2.0f * kPi));
    out.weighted += weight * rel * g;
    out.eq7 = true;
  }
}

}  // namespace

ProxyPlanes proxy_planes(const PosedProxies& proxies) {
  const std::size_t n = proxies.size();
  if (proxies.normal.size() != n || (proxies.radiance.size() != n && !proxies.radiance.empty()))
    throw std::invalid_argument("proxy_planes: " + std::to_string(n) + " positions, " + std::to_string(proxies.normal.size()) +
                                " normals and " + std::to_string(proxies.radiance.size()) + " radiances");
  ProxyPlanes v;
  v.size = n;
  std::vector<float>* planes[9] = {&v.px, &v.py, &v.pz, &v.nx, &v.ny, &v.nz, &v.lr, &v.lg, &v.lb};
  const std::vector<glm::vec3>* from[3] = {&proxies.position, &proxies.normal, &proxies.radiance};
  for (int k = 0; k < 9; ++k) {
    std::vector<float>& plane = *planes[k];
    plane.assign(n + kProxyLanes, 0.0f);
    const std::vector<glm::vec3>& src = *from[k / 3];
    if (src.empty()) continue;  // not lit yet
    for (std::size_t i = 0; i < n; ++i) plane[i] = src[i][k % 3];
  }
  return v;
}

void set_radiance(ProxyPlanes& planes, const PosedProxies& proxies) {
  const std::size_t n = proxies.size();
  if (planes.size != n || proxies.radiance.size() != n)
    throw std::invalid_argument("set_radiance: " + std::to_string(proxies.radiance.size()) + " radiances for planes of " +
                                std::to_string(planes.size) + " proxies");
  for (std::size_t i = 0; i < n; ++i) {
    planes.lr[i] = proxies.radiance[i].x;
    planes.lg[i] = proxies.radiance[i].y;
    planes.lb[i] = proxies.radiance[i].z;
  }
}

namespace {

// Eq. 6's near case for a diffuse receiver at p with normal nr: sum over VPLs [b, e) of
// L_i A cos_v cos_r / (d^2 + A / pi), kProxyLanes VPLs at a time, lanes past e counting 0. With w the
// vector to the VPL, cos_r cos_v = (nr . w)(-n_i . w) / d^2: no square root, one division. Compiled
// for several instruction sets; -ffp-contract=off for this file keeps every version's bits those
// of the baseline.
__attribute__((target_clones("avx512f", "avx2", "default"))) glm::vec3 near_diffuse(const ProxyPlanes& v, std::uint32_t b,
                                                                                    std::uint32_t e, glm::vec3 p, glm::vec3 nr,
                                                                                    float area, float reg) {
  float sr[kProxyLanes] = {}, sg[kProxyLanes] = {}, sb[kProxyLanes] = {};
  const float *px = v.px.data(), *py = v.py.data(), *pz = v.pz.data();
  const float *nx = v.nx.data(), *ny = v.ny.data(), *nz = v.nz.data();
  const float *lr = v.lr.data(), *lg = v.lg.data(), *lb = v.lb.data();
  for (std::uint32_t i = b; i < e; i += kProxyLanes) {
    const int left = static_cast<int>(e - i);
    for (std::size_t l = 0; l < kProxyLanes; ++l) {
      const std::size_t j = i + l;
      const float wx = px[j] - p.x, wy = py[j] - p.y, wz = pz[j] - p.z;
      const float d2 = wx * wx + wy * wy + wz * wz;
      const float dr = nr.x * wx + nr.y * wy + nr.z * wz;
      const float dv = -(nx[j] * wx + ny[j] * wy + nz[j] * wz);
      const bool ok = (static_cast<int>(l) < left) & (d2 > 0.0f) & (dr > 0.0f) & (dv > 0.0f);
      const float f = area * (dr * dv) / (d2 * (d2 + reg));
      const float fk = ok ? f : 0.0f;
      sr[l] += lr[j] * fk;
      sg[l] += lg[j] * fk;
      sb[l] += lb[j] * fk;
    }
  }
  glm::vec3 sum(0.0f);
  for (std::size_t l = 0; l < kProxyLanes; ++l) sum += glm::vec3(sr[l], sg[l], sb[l]);
  return sum;
}

// 2^y and log2(x) written for the vectoriser (no calls, no branches), for near_glossy's powers and
// Gaussians in lanes. exp2_lanes: y rounded to n + f, |f| <= 1/2 (the 1.5 * 2^23 trick, exact below
// 2^22 with contraction off), 2^f by Taylor's series of e^(f ln 2) to degree 7 (remainder below
// 6e-9 relative), times 2^n through the exponent bits; below 2^-125: 0. log2_lanes (x a positive
// normal float): x = 2^e m with m in [sqrt(1/2), sqrt(2)), ln m = 2 atanh(t), t = (m - 1)/(m + 1),
// |t| <= 0.172, by its series to t^11 (remainder below 1e-10).
__attribute__((always_inline)) inline float exp2_lanes(float y) {
  const float yc = std::min(std::max(y, -125.0f), 127.0f);
  const float r = (yc + 12582912.0f) - 12582912.0f;
  const float u = (yc - r) * 0.693147181f;
  const float q =
      1.0f + u * (1.0f + u * (0.5f + u * (1.0f / 6.0f + u * (1.0f / 24.0f + u * (1.0f / 120.0f + u * (1.0f / 720.0f + u * (1.0f / 5040.0f)))))));
  const std::int32_t n = static_cast<std::int32_t>(r);
  const float scale = std::bit_cast<float>(static_cast<std::uint32_t>(n + 127) << 23);
  return y < -125.0f ? 0.0f : q * scale;
}

__attribute__((always_inline)) inline float log2_lanes(float x) {
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(x);
  const float m0 = std::bit_cast<float>((bits & 0x007fffffu) | 0x3f800000u);
  const bool high = m0 > 1.41421356f;
  const float m = high ? 0.5f * m0 : m0;
  const float e = static_cast<float>(static_cast<std::int32_t>(bits >> 23) - 127 + (high ? 1 : 0));
  const float t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
  const float ln_m = 2.0f * t * (1.0f + t2 * (1.0f / 3.0f + t2 * (1.0f / 5.0f + t2 * (1.0f / 7.0f + t2 * (1.0f / 9.0f + t2 * (1.0f / 11.0f))))));
  return e + ln_m * 1.44269504f;
}

// Eq. 6's near case for a glossy receiver: gather_voxel's loop over VPLs [b, e) (the irradiance
// L_i A cos_v cos_r / (d^2 + A / pi), the Phong lobe's term and, with EQ7, eq. 7's weighted term of
// each light) kProxyLanes VPLs at a time, the power cos^ns as 2^(ns log2 cos) and eq. 7's Gaussian
// as 2^(-x^2 / (2 ln 2)). `any` is set where some light lies in the lobe's half-space.
struct NearGlossy {
  glm::vec3 irradiance{0.0f}, glossy{0.0f}, weighted{0.0f};
  bool any = false;
};
template <bool EQ7>
__attribute__((always_inline)) inline NearGlossy near_glossy_body(const ProxyPlanes& v, std::uint32_t b, std::uint32_t e,
                                                                  glm::vec3 p, glm::vec3 nr, glm::vec3 refl, float ns,
                                                                  float lobe_norm, float area, float reg, float sigma) {
  float er[kProxyLanes] = {}, eg[kProxyLanes] = {}, eb[kProxyLanes] = {};
  float gr[kProxyLanes] = {}, gg[kProxyLanes] = {}, gb[kProxyLanes] = {};
  float wr[kProxyLanes] = {}, wg[kProxyLanes] = {}, wb[kProxyLanes] = {};
  int hit[kProxyLanes] = {};
  const float *px = v.px.data(), *py = v.py.data(), *pz = v.pz.data();
  const float *nx = v.nx.data(), *ny = v.ny.data(), *nz = v.nz.data();
  const float *lr = v.lr.data(), *lg = v.lg.data(), *lb = v.lb.data();
  // exp(-x^2 / 2) = 2^(-x^2 / (2 ln 2)) with x = |1 - c^ns| / sigma.
  const float gauss = EQ7 ? -0.5f * 1.44269504f / (sigma * sigma) : 0.0f;
  for (std::uint32_t i = b; i < e; i += kProxyLanes) {
    const int left = static_cast<int>(e - i);
    for (std::size_t l = 0; l < kProxyLanes; ++l) {
      const std::size_t j = i + l;
      const float wx = px[j] - p.x, wy = py[j] - p.y, wz = pz[j] - p.z;
      const float d2 = wx * wx + wy * wy + wz * wz;
      const float inv = 1.0f / std::sqrt(d2 > 0.0f ? d2 : 1.0f);
      const float ux = wx * inv, uy = wy * inv, uz = wz * inv;
      const float cos_r = nr.x * ux + nr.y * uy + nr.z * uz;
      const float cos_v = -(nx[j] * ux + ny[j] * uy + nz[j] * uz);
      const bool ok = (static_cast<int>(l) < left) & (d2 > 0.0f) & (cos_r > 0.0f) & (cos_v > 0.0f);
      const float f = ok ? area * cos_v * cos_r / (d2 + reg) : 0.0f;
      const float ir = lr[j] * f, ig = lg[j] * f, ib = lb[j] * f;
      er[l] += ir;
      eg[l] += ig;
      eb[l] += ib;
      const float ca = refl.x * ux + refl.y * uy + refl.z * uz;
      const bool lobe = ok & (ca > 0.0f);
      const float pw = exp2_lanes(ns * log2_lanes(lobe ? ca : 1.0f));
      const float k = lobe ? lobe_norm * pw : 0.0f;
      gr[l] += ir * k;
      gg[l] += ig * k;
      gb[l] += ib * k;
      if constexpr (EQ7) {
        const float dx = 1.0f - pw;
        const float rel = exp2_lanes(gauss * dx * dx);
        wr[l] += ir * k * rel;
        wg[l] += ig * k * rel;
        wb[l] += ib * k * rel;
      }
      hit[l] |= lobe ? 1 : 0;
    }
  }
  NearGlossy out;
  for (std::size_t l = 0; l < kProxyLanes; ++l) {
    out.irradiance += glm::vec3(er[l], eg[l], eb[l]);
    out.glossy += glm::vec3(gr[l], gg[l], gb[l]);
    out.weighted += glm::vec3(wr[l], wg[l], wb[l]);
    out.any = out.any || hit[l] != 0;
  }
  return out;
}
// The Phong lobe alone, and with eq. 7 (sigma > 0); one version per instruction set of each.
__attribute__((target_clones("avx512f", "avx2", "default"))) NearGlossy near_glossy_phong(
    const ProxyPlanes& v, std::uint32_t b, std::uint32_t e, glm::vec3 p, glm::vec3 nr, glm::vec3 refl, float ns,
    float lobe_norm, float area, float reg) {
  return near_glossy_body<false>(v, b, e, p, nr, refl, ns, lobe_norm, area, reg, 0.0f);
}
__attribute__((target_clones("avx512f", "avx2", "default"))) NearGlossy near_glossy_eq7(
    const ProxyPlanes& v, std::uint32_t b, std::uint32_t e, glm::vec3 p, glm::vec3 nr, glm::vec3 refl, float ns,
    float lobe_norm, float area, float reg, float sigma) {
  return near_glossy_body<true>(v, b, e, p, nr, refl, ns, lobe_norm, area, reg, sigma);
}

}  // namespace

void gather_voxel(const VoxelGrid& grid, const PosedProxies& proxies, std::int32_t voxel, const Receiver& r,
                  float near_range, float weight, Gathered& out, const ProxyPlanes* planes) {
  const auto k = static_cast<std::size_t>(voxel);
  const std::uint32_t b = grid.start[k], e = grid.start[k + 1];
  if (b == e) return;
  const bool glossy = r.glossy > 0.0f;
  const float lobe_norm = (r.ns + 2.0f) / (2.0f * kPi);
  const glm::vec3 to_c = grid.centroid[k] - r.position;
  const float dc2 = glm::dot(to_c, to_c);
  if (dc2 < near_range * near_range) {
    // Near: each VPL a disc (eq. 6, first case).
    const float area = proxies.patch_area, reg = area / kPi;
    if (planes != nullptr) {
      if (planes->size != proxies.size())
        throw std::invalid_argument("gather_voxel: proxy planes of " + std::to_string(planes->size) + " proxies for " +
                                    std::to_string(proxies.size()));
      if (!glossy) {
        out.irradiance += weight * near_diffuse(*planes, b, e, r.position, r.normal, area, reg);
        return;
      }
      const NearGlossy g =
          r.eq7_sigma > 0.0f ? near_glossy_eq7(*planes, b, e, r.position, r.normal, r.reflect, r.ns, lobe_norm, area, reg, r.eq7_sigma)
                             : near_glossy_phong(*planes, b, e, r.position, r.normal, r.reflect, r.ns, lobe_norm, area, reg);
      out.irradiance += weight * g.irradiance;
      out.glossy += weight * g.glossy;
      if (r.eq7_sigma > 0.0f) {
        out.weighted += weight * g.weighted;
        out.eq7 = out.eq7 || g.any;
      }
      return;
    }
    glm::vec3 e_sum(0.0f);
    for (std::uint32_t i = b; i < e; ++i) {
      const glm::vec3 w = proxies.position[i] - r.position;
      const float d2 = glm::dot(w, w);
      if (!(d2 > 0.0f)) continue;
      const glm::vec3 wn = w / std::sqrt(d2);
      const float cos_r = glm::dot(r.normal, wn), cos_v = -glm::dot(proxies.normal[i], wn);
      if (cos_r <= 0.0f || cos_v <= 0.0f) continue;
      const glm::vec3 ei = proxies.radiance[i] * (area * cos_v * cos_r / (d2 + reg));
      e_sum += ei;
      if (glossy) add_glossy(r, ei, wn, lobe_norm, weight, out);
    }
    out.irradiance += weight * e_sum;
    return;
  }
  // Far: the voxel's SH intensity from its centroid (eq. 6, second case; eqs. 2-3).
  const float dc = std::sqrt(dc2);
  const glm::vec3 wn = to_c / dc;  // receiver -> voxel
  const float cos_r = glm::dot(r.normal, wn);
  if (cos_r <= 0.0f) return;
  const auto y = basis2(-wn);
  const auto& c = grid.sh[k];
  const glm::vec3 intensity = glm::max(glm::vec3(0.0f), c[0] * y[0] + c[1] * y[1] + c[2] * y[2] + c[3] * y[3]);
  const glm::vec3 ei = intensity * (cos_r / dc2);
  out.irradiance += weight * ei;
  if (glossy) add_glossy(r, ei, wn, lobe_norm, weight, out);
}

// --- Depth maps ------------------------------------------------------------------------------------

namespace {

struct ScreenVertex {
  float x, y, w;  // texel coordinates and the attribute interpolated linearly on screen
};

// Fills every texel whose centre the triangle covers with the interpolated w, keeping the smallest
// (keep_max: the largest) per texel.
void raster_triangle(const ScreenVertex& a, const ScreenVertex& b, const ScreenVertex& c, int size, float* texels, bool keep_max) {
  const float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  if (!(std::abs(area) > 1e-12f) || !std::isfinite(area)) return;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x, b.x, c.x}))));
  const int x1 = std::min(size - 1, static_cast<int>(std::ceil(std::max({a.x, b.x, c.x}))));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y, b.y, c.y}))));
  const int y1 = std::min(size - 1, static_cast<int>(std::ceil(std::max({a.y, b.y, c.y}))));
  const float inv = 1.0f / area;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const float px = x + 0.5f, py = y + 0.5f;
      const float w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) * inv;
      const float w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) * inv;
      const float w2 = 1.0f - w0 - w1;
      if (w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) continue;
      const float v = w0 * a.w + w1 * b.w + w2 * c.w;
      float& t = texels[static_cast<std::size_t>(y) * size + x];
      if (keep_max ? v > t : v < t) t = v;
    }
}

void check_size(int size, const char* what) {
  if (size < 1 || size > 8192) throw std::invalid_argument(std::string(what) + ": size " + std::to_string(size) + " (expected 1 to 8192)");
}

}  // namespace

CubeDepthMap rasterize_cube_depth(const scene::PosedScene& posed, const glm::vec3& center, int size, render::FramePool* pool) {
  check_size(size, "cube depth map");
  CubeDepthMap m;
  m.center = center;
  m.size = size;
  // Rasterised as 1/z (affine on screen under a perspective projection), the largest kept.
  const std::size_t texels = static_cast<std::size_t>(6) * size * size;
  std::vector<float> inv = pool ? pool->take<float>(texels, 0.0f) : std::vector<float>(texels, 0.0f);
  const float near = kCubeNear;
  // A face's texels are its own: the faces run in parallel, each over the triangles in scene order.
  tbb::parallel_for(0, 6, [&](int face) {
    const int a = face / 2, ua = (a + 1) % 3, va = (a + 2) % 3;
    const float s = face % 2 == 0 ? 1.0f : -1.0f;
    float* face_texels = inv.data() + static_cast<std::size_t>(face) * size * size;
    for (const auto& obj : posed.objects)
      for (const auto& t : obj.source->triangles) {
        const glm::vec3 d[3] = {obj.positions[t.x] - center, obj.positions[t.y] - center, obj.positions[t.z] - center};
        // Clip against z > near (Sutherland-Hodgman), then fan.
        glm::vec3 poly[4];
        int n = 0;
        for (int i = 0; i < 3; ++i) {
          const glm::vec3 p(d[i][ua], d[i][va], s * d[i][a]), q(d[(i + 1) % 3][ua], d[(i + 1) % 3][va], s * d[(i + 1) % 3][a]);
          const bool pin = p.z > near, qin = q.z > near;
          if (pin) poly[n++] = p;
          if (pin != qin) poly[n++] = p + (q - p) * ((near - p.z) / (q.z - p.z));
        }
        if (n < 3) continue;
        ScreenVertex sv[4];
        for (int i = 0; i < n; ++i) {
          const float x = poly[i].x / poly[i].z, y = poly[i].y / poly[i].z;
          sv[i] = {(x + 1.0f) * 0.5f * size, (y + 1.0f) * 0.5f * size, 1.0f / poly[i].z};
        }
        for (int i = 1; i + 1 < n; ++i) raster_triangle(sv[0], sv[i], sv[i + 1], size, face_texels, true);
      }
  });
  m.depth = pool ? pool->take_for_overwrite<float>(texels) : std::vector<float>(texels);
  for (std::size_t i = 0; i < texels; ++i) m.depth[i] = inv[i] > 0.0f ? 1.0f / inv[i] : kInf;
  if (pool) pool->give(std::move(inv));
  return m;
}

float CubeDepthMap::visibility(const glm::vec3& p, const glm::vec3& p_normal) const {
  glm::vec3 d = p - center;
  const float dist = glm::length(d);
  if (!(dist > 0.0f)) return 1.0f;
  // Offset along the normal by two texels' footprint at this distance (90-degree faces: 2 / size).
  d += p_normal * (2.0f * 2.0f * dist / static_cast<float>(size));
  int a = 0;
  if (std::abs(d.y) > std::abs(d[a])) a = 1;
  if (std::abs(d.z) > std::abs(d[a])) a = 2;
  const int face = 2 * a + (d[a] < 0.0f ? 1 : 0), ua = (a + 1) % 3, va = (a + 2) % 3;
  const float z = std::abs(d[a]);
  const float fx = (d[ua] / z + 1.0f) * 0.5f * size, fy = (d[va] / z + 1.0f) * 0.5f * size;
  const int cx = std::clamp(static_cast<int>(fx), 0, size - 1), cy = std::clamp(static_cast<int>(fy), 0, size - 1);
  const float bias = z * (1e-3f + 2.0f / static_cast<float>(size));
  int lit = 0, n = 0;
  for (int j = cy - 1; j <= cy + 1; ++j)
    for (int i = cx - 1; i <= cx + 1; ++i) {
      if (i < 0 || j < 0 || i >= size || j >= size) continue;
      ++n;
      lit += z <= depth[(static_cast<std::size_t>(face) * size + j) * size + i] + bias;
    }
  return n ? static_cast<float>(lit) / static_cast<float>(n) : 1.0f;
}

OrthoDepthMap ortho_frame(const scene::PosedScene& posed, const glm::vec3& towards_light, int size) {
  check_size(size, "directional depth map");
  OrthoDepthMap m;
  m.size = size;
  m.dir = glm::normalize(towards_light);
  const glm::vec3 t = std::abs(m.dir.y) > 0.9f ? glm::vec3(1.0f, 0.0f, 0.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
  m.u = glm::normalize(glm::cross(t, m.dir));
  m.v = glm::cross(m.dir, m.u);
  glm::vec2 lo(kInf), hi(-kInf);
  for (const auto& obj : posed.objects)
    for (const auto& p : obj.positions) {
      const glm::vec2 q(glm::dot(p, m.u), glm::dot(p, m.v));
      lo = glm::min(lo, q);
      hi = glm::max(hi, q);
    }
  if (!(lo.x <= hi.x)) lo = hi = glm::vec2(0.0f);
  const glm::vec2 pad = glm::max((hi - lo) * 0.01f, glm::vec2(1e-4f));
  m.lo = lo - pad;
  m.extent = hi + pad - m.lo;
  return m;
}

OrthoDepthMap rasterize_ortho_depth(const scene::PosedScene& posed, const glm::vec3& towards_light, int size,
                                    render::FramePool* pool) {
  OrthoDepthMap m = ortho_frame(posed, towards_light, size);
  const std::size_t texels = static_cast<std::size_t>(size) * size;
  if (pool)
    m.depth = pool->take<float>(texels, kInf);
  else
    m.depth.assign(texels, kInf);
  for (const auto& obj : posed.objects)
    for (const auto& tri : obj.source->triangles) {
      ScreenVertex sv[3];
      for (int i = 0; i < 3; ++i) {
        const glm::vec3& p = obj.positions[tri[i]];
        sv[i] = {(glm::dot(p, m.u) - m.lo.x) / m.extent.x * size, (glm::dot(p, m.v) - m.lo.y) / m.extent.y * size, -glm::dot(p, m.dir)};
      }
      raster_triangle(sv[0], sv[1], sv[2], size, m.depth.data(), false);
    }
  return m;
}

float OrthoDepthMap::visibility(const glm::vec3& p, const glm::vec3& p_normal) const {
  const float texel = std::max(extent.x, extent.y) / static_cast<float>(size);
  const glm::vec3 q = p + p_normal * (2.0f * texel);
  const float fx = (glm::dot(q, u) - lo.x) / extent.x * size, fy = (glm::dot(q, v) - lo.y) / extent.y * size;
  const int cx = static_cast<int>(std::floor(fx)), cy = static_cast<int>(std::floor(fy));
  const float z = -glm::dot(q, dir), bias = 2.0f * texel;
  int lit = 0, n = 0;
  for (int j = cy - 1; j <= cy + 1; ++j)
    for (int i = cx - 1; i <= cx + 1; ++i) {
      ++n;
      if (i < 0 || j < 0 || i >= size || j >= size) {
        ++lit;  // outside the scene's footprint: nothing in front
        continue;
      }
      lit += z <= depth[static_cast<std::size_t>(j) * size + i] + bias;
    }
  return static_cast<float>(lit) / static_cast<float>(n);
}

}  // namespace softgi::techniques::point_voxels
