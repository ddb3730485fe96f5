// Spherical lights (paper 001, Guerrero, Jeschke and Wimmer 2008) as a render::Technique: each
// proxy sphere of an object is a blocker and a low-frequency secondary light. Per frame, the SLs'
// sample points are lit by the environment under the SLs' shadows (section 5.1), each SL's
// intensity is projected to SH (section 5.2), and per-vertex receivers sum the SLs' average
// radiance times their average visibility (section 6) beside SHEXP-style direct soft shadows.
// docs/techniques/spherical_lights.md describes the graph and the measurements.
#include "softgi/techniques/spherical_lights.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "sl_passes.hpp"
#include "../common/device_kernels.hpp"
#include "../common/pass_support.hpp"
#include "../common/shared_params.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/vertex_image.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::techniques::spherical_lights {

std::vector<render::ExperimentDef> experiments();  // sl_experiments.cpp

Settings read_settings(const render::ParamSet& p) {
  Settings s;
  s.order = p.get_int("order");
  s.exp = p.get_enum("exp") == "ol" ? sh::ExpMethod::OL : sh::ExpMethod::HYB;
  s.window_h = common::params::read_window_h(p, s.order);
  s.rule = common::params::read_replacement_rule(p);
  s.table_resolution = p.get_int("table_resolution");
  s.log_threshold = p.get_float("log_threshold");
  s.lights = p.get_bool("analytic_lights");
  s.lights_as_sls = p.get_enum("local_lights") == "sl";
  s.isa = common::params::read_kernel(p);
  s.blocking = p.get_enum("blocking") == "per_object" ? Blocking::PerObject : Blocking::PerSphere;
  s.indirect = p.get_bool("indirect");
  s.clusters = p.get_int("receiver_clusters");
  s.hierarchy = p.get_bool("hierarchy");
  s.reflection_ratios = p.get_bool("reflection_ratios");
  s.shadow_hierarchy = p.get_bool("shadow_hierarchy");
  if (s.shadow_hierarchy && !s.hierarchy)
    throw std::invalid_argument("spherical_lights: shadow_hierarchy=true needs hierarchy=true (the shadows are cut from the SL "
                                "hierarchies)");
  s.theta_max = p.get_float("theta_max_deg") * sh::kPi / 180.0;
  s.pre.order = s.order;
  s.pre.geodesic_frequency = p.get_int("geodesic_frequency");
  s.pre.cubemap_resolution = p.get_int("cubemap_resolution");
  s.pre.projection_strata = p.get_int("projection_strata");
  s.visibility = p.get_enum("indirect_visibility") == "ray_cast" ? IndirectVisibility::RayCast : IndirectVisibility::Sh;
  s.ray_strata = p.get_int("ray_strata");
  s.pre.intersecting = p.get_enum("intersecting") == "run_time" ? IntersectingOcclusion::RunTime : IntersectingOcclusion::Precomputed;
  if (s.pre.intersecting == IntersectingOcclusion::RunTime && s.visibility != IndirectVisibility::RayCast)
    throw std::invalid_argument("spherical_lights: intersecting=run_time needs indirect_visibility=ray_cast (the blocker function of "
                                "an intersecting SL is not circularly symmetric, so the SH visibility cannot resolve it; paper 001 "
                                "section 6.2)");
  return s;
}

std::size_t SlData::bytes() const {
  std::size_t b = 0;
  for (const auto& o : objects) b += o.data ? o.data->bytes() : 0;
  return b;
}

std::size_t SlPose::bytes() const {
  std::size_t b = size() * (sizeof(glm::vec3) + sizeof(float) + sizeof(glm::mat3) + sizeof(int));
  for (const auto& x : intersecting) b += x.size() * sizeof(int);
  b += samples.size() * (6 * sizeof(float) + sizeof(const float*)) + blockers.bytes();
  return b;
}

std::shared_ptr<const Tables> make_tables(int order, int resolution, double log_threshold) {
  auto tab = std::make_shared<Tables>();
  tab->order = order;
  tab->sh = common::accumulation_tables(order, resolution, log_threshold);
  tab->log = make_zh_table(tab->sh->cap_log(), order, true);
  tab->weight = weight_table_from(tab->sh->sl_weight(), order);
  return tab;
}

namespace {

using render::FrameContext;
using render::ParamDesc;

// 64-bit FNV-1a over the words of what an object's precomputation depends on.
class Fnv {
 public:
  void word(std::uint32_t w) { h_ = (h_ ^ w) * 1099511628211ull; }
  void f(float x) { word(std::bit_cast<std::uint32_t>(x)); }
  void v3(const glm::vec3& v) {
    f(v.x);
    f(v.y);
    f(v.z);
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 14695981039346656037ull;
};

// Everything precompute_object reads: the rest mesh, its material and texture, the sphere set and
// the options. Hashed every frame (linear in the mesh, far below the frame's own work) so that a
// scene edited in place is never served a stale precomputation.
std::string object_key(const scene::Scene& scene, int set, const PrecomputeOptions& opt) {
  const scene::ProxySet& ps = scene.proxies[set];
  Fnv h;
  h.word(static_cast<std::uint32_t>(ps.node));
  for (const auto& sp : ps.spheres) {
    h.v3(sp.center);
    h.f(sp.radius);
  }
  const scene::Node& node = scene.nodes[ps.node];
  const scene::Mesh& m = scene.meshes[node.mesh];
  for (const auto& p : m.positions) h.v3(p);
  for (const auto& n : m.normals) h.v3(n);
  for (const auto& t : m.triangles) {
    h.word(t.x);
    h.word(t.y);
    h.word(t.z);
  }
  for (const auto& uv : m.uvs) {
    h.f(uv.x);
    h.f(uv.y);
  }
  for (const auto& c : m.colors) h.v3(c);
  if (m.material >= 0 && m.material < static_cast<int>(scene.materials.size())) {
    const scene::Material& mat = scene.materials[m.material];
    h.v3(mat.albedo);
    if (mat.albedo_texture >= 0 && mat.albedo_texture < static_cast<int>(scene.textures.size())) {
      const scene::Texture& tex = scene.textures[mat.albedo_texture];
      h.word(static_cast<std::uint32_t>(tex.width));
      h.word(static_cast<std::uint32_t>(tex.height));
      for (const auto& t : tex.texels) h.v3(t);
    }
  }
  std::ostringstream os;
  os << opt.order << '|' << opt.geodesic_frequency << '|' << opt.cubemap_resolution << '|' << opt.projection_strata << '|'
     << opt.seed << '|' << static_cast<int>(opt.intersecting) << '|' << std::hex << h.value();
  return os.str();
}

struct State {
  std::mutex m;
  common::SharedCache<std::tuple<int, int, double>, Tables> tables;
  common::LightTableCache light_tables;
  std::map<std::string, SlObject> objects;  // precomputations by object_key (set and object filled per frame)
  std::string env_key;
  std::vector<glm::vec3> env_sh;
  common::ReceiverClustering receivers;
};

// The rotation of M's upper 3x3: the polar factor by the Newton iteration X <- (X + X^-T)/2 of
// Higham 1986, which converges quadratically for a non-singular X; identity when M is singular or
// a reflection.
glm::mat3 polar_rotation(glm::mat3 x) {
  const float d0 = glm::determinant(x);
  if (!(std::abs(d0) > 1e-12f) || !std::isfinite(d0)) return glm::mat3(1.0f);
  for (int it = 0; it < 30; ++it) {
    const glm::mat3 next = 0.5f * (x + glm::transpose(glm::inverse(x)));
    float diff = 0.0f;
    for (int c = 0; c < 3; ++c) diff = std::max(diff, glm::length(next[c] - x[c]));
    x = next;
    if (diff < 1e-7f) break;
  }
  return glm::determinant(x) > 0.0f ? x : glm::mat3(1.0f);
}

// Section 7.1, soft deformations: the SL moves with the average rotation and translation of its
// associated vertices, the similarity (s, R, t) that best maps their rest positions onto the posed
// ones in the least-squares sense (the cross-covariance's polar rotation and the scale of Umeyama
// 1991). For a rigidly moved object it is the node's own motion.
struct Similarity {
  glm::mat3 R{1.0f};
  float s = 1.0f;
  glm::vec3 t{0.0f};
};
bool fit_similarity(const std::vector<glm::vec3>& rest, const std::vector<glm::vec3>& posed, const std::vector<std::uint32_t>& vertices,
                    Similarity& out) {
  if (vertices.size() < 3) return false;
  glm::dvec3 pr(0.0), pp(0.0);
  for (std::uint32_t v : vertices) {
    pr += glm::dvec3(rest[v]);
    pp += glm::dvec3(posed[v]);
  }
  pr /= static_cast<double>(vertices.size());
  pp /= static_cast<double>(vertices.size());
  glm::dmat3 H(0.0);
  double var = 0.0;
  for (std::uint32_t v : vertices) {
    const glm::dvec3 a = glm::dvec3(rest[v]) - pr, b = glm::dvec3(posed[v]) - pp;
    H += glm::outerProduct(b, a);
    var += glm::dot(a, a);
  }
  if (!(var > 0.0)) return false;
  // Collinear or coplanar-degenerate vertex sets leave the rotation about their line undetermined.
  const double scale = std::cbrt(std::abs(glm::determinant(H)));
  if (!(scale > 1e-9 * var)) return false;
  const glm::mat3 R = polar_rotation(glm::mat3(H));
  double tr = 0.0;
  const glm::dmat3 Rd(R);
  for (int c = 0; c < 3; ++c) tr += glm::dot(Rd[c], H[c]);
  out.R = R;
  out.s = static_cast<float>(tr / var);
  out.t = glm::vec3(pp - static_cast<double>(out.s) * (Rd * pr));
  return out.s > 0.0f && std::isfinite(out.s);
}

void pass_tables(State& st, const Settings& s, FrameContext& ctx) {
  bool cached = false;
  const std::shared_ptr<const Tables> t = st.tables.get(
      std::make_tuple(s.order, s.table_resolution, s.log_threshold),
      [&s] { return make_tables(s.order, s.table_resolution, s.log_threshold); },
      cached);
  auto& rec = ctx.record();
  rec.counters["order"] = s.order;
  rec.counters["rows"] = s.table_resolution;
  rec.counters["cached"] = cached;
  rec.counters["weight_table_bytes"] = static_cast<double>(t->weight.bytes());
  rec.bytes = t->bytes();
  ctx.put<std::shared_ptr<const Tables>>(kTables, t);
}

// Section 4: the SLs' sample points, albedo and projection sums per object, computed once per
// object and reused while its rest mesh, material and spheres stay the same.
void pass_setup(State& st, const Settings& s, FrameContext& ctx) {
  common::check_proxy_spheres("spherical_lights", ctx, false);
  auto data = std::make_shared<SlData>();
  std::map<int, int> object_of_node;
  for (std::size_t o = 0; o < ctx.posed.objects.size(); ++o) object_of_node[ctx.posed.objects[o].node] = static_cast<int>(o);
  int computed = 0, cached = 0;
  double samples = 0.0, kept = 0.0, parents = 0.0;
  for (std::size_t set = 0; set < ctx.scene.proxies.size(); ++set) {
    const scene::ProxySet& ps = ctx.scene.proxies[set];
    if (ps.spheres.empty()) continue;
    auto it = object_of_node.find(ps.node);
    if (it == object_of_node.end()) {
      ctx.warn("spherical_lights: proxy set '" + ps.name + "' bounds no object with a mesh: its spheres block but emit nothing");
      continue;
    }
    const bool tree = s.hierarchy && ps.spheres.size() > 1;
    const std::string key = object_key(ctx.scene, static_cast<int>(set), s.pre) + (tree ? "|tree" : "");
    SlObject so;
    {
      std::lock_guard<std::mutex> lock(st.m);
      auto f = st.objects.find(key);
      if (f != st.objects.end()) so = f->second;
    }
    if (so.data) {
      ++cached;
    } else {
      // Section 7.3: parents bound about four children each (paper 004 section 6.3), built over the
      // rest-pose leaves; each parent is an SL of its own over the union of its leaves' segments.
      std::vector<SlGroup> groups;
      if (tree) {
        so.tree = std::make_shared<const proxies::SphereHierarchy>(proxies::SphereHierarchy::build(ps.spheres, proxies::HierarchyBuildOptions{}));
        const auto& nodes = so.tree->nodes();
        so.node_group.assign(nodes.size(), -1);
        for (std::size_t nd = 0; nd < nodes.size(); ++nd) {
          if (nodes[nd].children.empty()) continue;
          SlGroup g;
          g.sphere = nodes[nd].bound;
          std::vector<int> stack(1, static_cast<int>(nd));
          while (!stack.empty()) {
            const int id = stack.back();
            stack.pop_back();
            if (nodes[id].children.empty()) g.leaves.push_back(nodes[id].leaf);
            for (int ch : nodes[id].children) stack.push_back(ch);
          }
          std::sort(g.leaves.begin(), g.leaves.end());
          so.node_group[nd] = static_cast<int>(groups.size());
          groups.push_back(std::move(g));
        }
      }
      so.data = std::make_shared<const ObjectSls>(precompute_object(ctx.scene, ps.node, ps, s.pre, tree ? &groups : nullptr));
      ++computed;
      std::lock_guard<std::mutex> lock(st.m);
      st.objects[key] = so;
    }
    so.set = static_cast<int>(set);
    so.object = it->second;
    for (const auto* list : {&so.data->sls, &so.data->groups})
      for (const auto& sl : *list) {
        samples += static_cast<double>(so.data->directions.size());
        kept += static_cast<double>(sl.sample_count());
      }
    parents += static_cast<double>(so.data->groups.size());
    data->objects.push_back(std::move(so));
  }
  auto& rec = ctx.record();
  rec.counters["objects"] = static_cast<double>(data->objects.size());
  rec.counters["parent_sls"] = parents;
  rec.counters["computed"] = computed;
  rec.counters["cached"] = cached;
  rec.counters["sample_points"] = kept;
  rec.counters["sample_directions"] = samples;
  rec.bytes = data->bytes();
  ctx.put<std::shared_ptr<const SlData>>(kSlData, data);
}

// Section 7.1: this frame's SLs with their rotation, and their sample points moved with them. Leaves
// are the posed proxy spheres; a parent moves with the similarity of its associated vertices (or
// its node).
void pass_pose(const Settings& s, FrameContext& ctx) {
  const auto& data = *ctx.get<std::shared_ptr<const SlData>>(kSlData);
  auto pose = std::make_shared<SlPose>();
  pose->order = s.order;
  pose->blockers.order = s.order;  // before the pushes: BlockerList::push fills `order` band weights
  std::size_t total_samples = 0, total_sls = 0;
  for (const auto& so : data.objects)
    for (const auto* list : {&so.data->sls, &so.data->groups}) {
      total_sls += list->size();
      for (const auto& sl : *list) total_samples += sl.sample_count();
    }
  pose->samples.resize(total_samples);
  pose->sample_begin.reserve(total_sls + 1);
  pose->basis.reserve(total_samples);
  int fallback = 0;
  std::size_t next = 0;
  const std::size_t n2 = static_cast<std::size_t>(s.order) * s.order;
  // Appends one SL with its sample points moved by the similarity (or the node matrix M).
  auto add_sl = [&](const SphericalLightData& sl, int oi, const glm::vec3& centre, float radius, bool fitted, const Similarity& sim,
                    const glm::mat4& M) {
    const glm::mat3 Nm = glm::transpose(glm::inverse(glm::mat3(M)));
    pose->centre.push_back(centre);
    pose->radius.push_back(radius);
    pose->object.push_back(oi);
    pose->albedo.push_back(sl.albedo_sh.data());
    pose->sample_begin.push_back(next);
    pose->rotation.push_back(fitted ? sim.R : polar_rotation(glm::mat3(M)));
    for (std::size_t k = 0; k < sl.sample_count(); ++k, ++next) {
      glm::vec3 p, n;
      if (fitted) {
        p = sim.s * (sim.R * sl.sample_positions[k]) + sim.t;
        n = sim.R * sl.sample_normals[k];
      } else {
        p = glm::vec3(M * glm::vec4(sl.sample_positions[k], 1.0f));
        n = glm::normalize(Nm * sl.sample_normals[k]);
      }
      pose->samples.set(next, p, n);
      pose->basis.push_back(sl.basis_sums.data() + k * n2);
    }
  };
  auto motion = [&](const SlObject& so, const SphericalLightData& sl, Similarity& sim) {
    const scene::PosedObject& obj = ctx.posed.objects[so.object];
    const scene::Mesh& mesh = *obj.source;
    const bool deforming = mesh.skinned() || obj.positions.size() != mesh.positions.size();
    if (!deforming) return false;
    if (obj.positions.size() != mesh.positions.size()) {
      ++fallback;
      return false;
    }
    if (fit_similarity(mesh.positions, obj.positions, sl.vertices, sim)) return true;
    // Too few associated vertices (a sphere nearest to almost none): the vertices inside it at rest.
    std::vector<std::uint32_t> inside;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
      if (glm::length(mesh.positions[v] - sl.sphere.center) <= sl.sphere.radius) inside.push_back(static_cast<std::uint32_t>(v));
    if (fit_similarity(mesh.positions, obj.positions, inside, sim)) return true;
    ++fallback;
    return false;
  };
  std::vector<std::size_t> base(data.objects.size());
  for (std::size_t oi = 0; oi < data.objects.size(); ++oi) {
    const SlObject& so = data.objects[oi];
    const std::vector<scene::Sphere>& spheres = ctx.posed.proxies[so.set];
    const glm::mat4 M = ctx.posed.node_world[ctx.posed.objects[so.object].node];
    base[oi] = pose->size();
    glm::vec3 centre_sum(0.0f);
    for (std::size_t i = 0; i < so.data->sls.size(); ++i) {
      const SphericalLightData& sl = so.data->sls[i];
      Similarity sim;
      const bool fitted = motion(so, sl, sim);
      add_sl(sl, static_cast<int>(oi), spheres[i].center, spheres[i].radius, fitted, sim, M);
      centre_sum += spheres[i].center;
      std::vector<int> inter;
      for (int j : sl.intersecting) inter.push_back(static_cast<int>(base[oi]) + j);
      pose->intersecting.push_back(std::move(inter));
      pose->leaves_below.push_back({static_cast<int>(pose->size() - 1)});
      pose->blockers.push(spheres[i].center, spheres[i].radius, nullptr);
    }
    pose->object_centre.push_back(so.data->sls.empty() ? glm::vec3(0.0f) : centre_sum / static_cast<float>(so.data->sls.size()));
  }
  pose->leaves = pose->size();
  // Section 7.3: the parents, after every leaf.
  pose->trees.resize(data.objects.size());
  pose->node_sl.resize(data.objects.size());
  for (std::size_t oi = 0; oi < data.objects.size(); ++oi) {
    const SlObject& so = data.objects[oi];
    if (!so.tree) continue;
    const glm::mat4 M = ctx.posed.node_world[ctx.posed.objects[so.object].node];
    const glm::mat3 M3(M);
    const float node_scale = std::max({glm::length(M3[0]), glm::length(M3[1]), glm::length(M3[2])});
    pose->trees[oi] = so.tree;
    const auto& nodes = so.tree->nodes();
    pose->node_sl[oi].assign(nodes.size(), -1);
    for (std::size_t nd = 0; nd < nodes.size(); ++nd) {
      if (nodes[nd].children.empty()) {
        pose->node_sl[oi][nd] = static_cast<int>(base[oi]) + nodes[nd].leaf;
        continue;
      }
      const SphericalLightData& sl = so.data->groups[so.node_group[nd]];
      Similarity sim;
      const bool fitted = motion(so, sl, sim);
      const glm::vec3 c = fitted ? sim.s * (sim.R * sl.sphere.center) + sim.t : glm::vec3(M * glm::vec4(sl.sphere.center, 1.0f));
      const float r = sl.sphere.radius * (fitted ? sim.s : node_scale);
      pose->node_sl[oi][nd] = static_cast<int>(pose->size());
      add_sl(sl, static_cast<int>(oi), c, r, fitted, sim, M);
      pose->intersecting.emplace_back();
      std::vector<int> below;
      std::vector<int> stack(1, static_cast<int>(nd));
      while (!stack.empty()) {
        const int id = stack.back();
        stack.pop_back();
        if (nodes[id].children.empty()) below.push_back(static_cast<int>(base[oi]) + nodes[id].leaf);
        for (int ch : nodes[id].children) stack.push_back(ch);
      }
      pose->leaves_below.push_back(std::move(below));
    }
  }
  pose->sample_begin.push_back(next);
  if (fallback > 0)
    ctx.warn("spherical_lights: " + std::to_string(fallback) +
             " deforming SLs have fewer than 3 non-collinear vertices in their segment or sphere and move with their node instead");
  auto& rec = ctx.record();
  rec.counters["sls"] = static_cast<double>(pose->size());
  rec.counters["leaf_sls"] = static_cast<double>(pose->leaves);
  rec.counters["sample_points"] = static_cast<double>(total_samples);
  rec.counters["node_motion_fallbacks"] = fallback;
  rec.bytes = pose->bytes();
  ctx.put<std::shared_ptr<const SlPose>>(kSlPose, pose);
}

// The receivers of a stage: the SLs' sample points (section 5.1) or the scene's vertices (section 6).
const ReceiverSoA& stage_receivers(FrameContext& ctx, Stage stage) {
  if (stage == Stage::Samples) return ctx.get<std::shared_ptr<const SlPose>>(kSlPose)->samples;
  return ctx.get<std::shared_ptr<const Receivers>>(kReceivers)->soa;
}

// Log-space accumulation of every SL as a blocker (paper 004 eqs. 8, 34 with the replacement rules
// of section 6.2; paper 001 eqs. 6-7).
void pass_accumulate(const Settings& s, FrameContext& ctx, Stage stage) {
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const ReceiverSoA& rec = stage_receivers(ctx, stage);
  const std::size_t n2 = static_cast<std::size_t>(s.order) * s.order, nr = rec.size();
  auto f = std::make_shared<Field>();
  f->order = s.order;
  f->v.assign(nr * n2, 0.0f);
  const auto t0 = std::chrono::steady_clock::now();
  double pairs = 0.0;
  if (stage == Stage::Samples && ctx.has(kSampleShadowCuts)) {
    // Each SL's sample points sum the cut of its object (one task per SL).
    const auto& cuts = *ctx.get<std::shared_ptr<const ClusterCuts>>(kSampleShadowCuts);
    auto list_of = [&](std::size_t i) -> const BlockerList& {
      return cuts.lists[static_cast<std::size_t>(cuts.list_of_cluster[static_cast<std::size_t>(pose.object[i])])];
    };
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pose.size(), 4), [&](const tbb::blocked_range<std::size_t>& sr) {
      for (std::size_t i = sr.begin(); i != sr.end(); ++i)
        accumulate_log(s.isa, t.log, s.rule, rec, pose.sample_begin[i], pose.sample_begin[i + 1], list_of(i), f->v.data());
    });
    for (std::size_t i = 0; i < pose.size(); ++i)
      pairs += static_cast<double>(pose.sample_begin[i + 1] - pose.sample_begin[i]) * static_cast<double>(list_of(i).size());
  } else if (stage == Stage::Receivers && ctx.has(kShadowCuts)) {
    // Section 7.3: each receiver cluster sums its cut (one task per cluster, as SHEXP's kernel).
    const auto& cuts = *ctx.get<std::shared_ptr<const ClusterCuts>>(kShadowCuts);
    const auto& receivers = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, receivers.clusters.size(), 1), [&](const tbb::blocked_range<std::size_t>& cr) {
      for (std::size_t c = cr.begin(); c != cr.end(); ++c) {
        const ReceiverCluster& rc = receivers.clusters[c];
        accumulate_log(s.isa, t.log, s.rule, rec, rc.begin, rc.end, cuts.lists[cuts.list_of_cluster[c]], f->v.data());
      }
    });
    for (std::size_t c = 0; c < receivers.clusters.size(); ++c)
      pairs += static_cast<double>(receivers.clusters[c].end - receivers.clusters[c].begin) *
               static_cast<double>(cuts.lists[cuts.list_of_cluster[c]].size());
  } else {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nr, 256), [&](const tbb::blocked_range<std::size_t>& br) {
      accumulate_log(s.isa, t.log, s.rule, rec, br.begin(), br.end(), pose.blockers, f->v.data());
    });
    pairs = static_cast<double>(nr) * static_cast<double>(pose.blockers.size());
  }
  const double secs = common::seconds_since(t0);
  auto& r = ctx.record();
  r.counters["receivers"] = static_cast<double>(nr);
  r.counters["blockers"] = static_cast<double>(pose.blockers.size());
  r.counters["pairs"] = pairs;
  r.counters["pairs_per_second"] = secs > 0.0 ? pairs / secs : 0.0;
  r.bytes = f->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(log_resource(stage), f);
}

// The SH exponential of the summed logs (paper 004 section 4).
void pass_exponentiate(const Settings& s, FrameContext& ctx, Stage stage) {
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& f = *ctx.get<std::shared_ptr<const Field>>(log_resource(stage));
  const std::size_t n2 = static_cast<std::size_t>(s.order) * s.order, nr = f.v.size() / n2;
  auto g = std::make_shared<Field>();
  g->order = s.order;
  g->v.assign(nr * n2, 0.0f);
  BatchExp be;
  be.order = s.order;
  be.method = s.exp;
  be.tables = t.sh.get();
  be.plan = &ProductPlan::get(s.order);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nr, 256), [&](const tbb::blocked_range<std::size_t>& br) {
    sh::ExpStats es;
    try {
      exp_batch(s.isa, be, f.v.data() + br.begin() * n2, g->v.data() + br.begin() * n2, br.size(), br.begin(), es);
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string("spherical_lights exponentiate (") + (stage == Stage::Samples ? "sample points" : "receivers") +
                               "): " + e.what());
    }
  });
  ctx.record().counters["receivers"] = static_cast<double>(nr);
  ctx.record().bytes = g->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Field>>(visibility_resource(stage), g);
}

// (H(N) * g) . L for the environment plus the analytic lights' L_H . g (paper 004 eq. 9, section
// 7), clamped at 0: the diffuse reflection of a white surface, E/pi. Unshadowed without visibility.
void pass_shade(State& st, const Settings& s, FrameContext& ctx, Stage stage, const common::ShadeKernel* kernel) {
  const ReceiverSoA& rec = stage_receivers(ctx, stage);
  const int n = s.order, n2 = n * n;
  const char* vres = visibility_resource(stage);
  const bool shadowed = ctx.has(vres);
  const bool vis_on_device = kernel && shadowed && ctx.is_deferred(vres);
  std::shared_ptr<const Field> vis;
  if (shadowed && !vis_on_device) vis = ctx.get<std::shared_ptr<const Field>>(vres);
  std::vector<glm::vec3> env;
  {
    const std::string key = common::environment_signature(ctx.scene.environment) + std::to_string(n) + '|' + std::to_string(s.window_h);
    std::lock_guard<std::mutex> lock(st.m);
    if (st.env_key != key) {
      st.env_sh = common::windowed_environment_sh("spherical_lights", ctx.scene, n, s.window_h);
      st.env_key = key;
    }
    env = st.env_sh;
  }
  std::vector<float> Lflat(3 * n2), hcoef(n2), gwin(n2, 1.0f);
  const std::vector<double> cc = sh::clamped_cosine_zh(n);
  for (int l = 0; l < n; ++l)
    for (int m = -l; m <= l; ++m) hcoef[sh::index(l, m)] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < n2; ++i) Lflat[c * n2 + i] = env[i][c];
  std::shared_ptr<const LightLobeTable> lt;
  if (ctx.has(kLightTables)) lt = ctx.get<std::shared_ptr<const LightLobeTable>>(kLightTables);
  const BatchShade bs = BatchShade::make(n, Lflat.data(), hcoef.data(), gwin.data(), vis ? vis->v.data() : nullptr);
  auto out = std::make_shared<Shading>();
  out->value.resize(rec.size());
  long long clamped = 0;
  if (kernel) {
    GpuShade in{&bs, lt.get(), &ctx.posed.lights, false, nullptr};
    if (vis_on_device) in.visibility_resource = vres;
    clamped = (*kernel)(ctx, in, rec, out->value.data());
  } else {
    std::atomic<long long> cl{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rec.size(), 256), [&](const tbb::blocked_range<std::size_t>& br) {
      shade_batch(s.isa, bs, rec, br.begin(), br.end(), out->value.data() + br.begin());
      cl += add_lights_and_clamp(s.isa, lt.get(), ctx.posed.lights, n, gwin.data(), rec, br.begin(), br.end(), bs.g, false,
                                 out->value.data() + br.begin());
    });
    clamped = cl.load();
  }
  // Section 7.3: the local lights as SLs, at the sample points (the first pass) and at the vertices.
  const bool local = s.lights && s.lights_as_sls && !ctx.posed.lights.empty();
  if (local) {
    const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
    const SlPose* pose = ctx.has(kSlPose) ? ctx.get<std::shared_ptr<const SlPose>>(kSlPose).get() : nullptr;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rec.size(), 64), [&](const tbb::blocked_range<std::size_t>& br) {
      add_local_lights(s, t, pose, ctx.posed.lights, rec, br.begin(), br.end(), out->value.data() + br.begin());
    });
  }
  auto& r = ctx.record();
  r.counters["receivers"] = static_cast<double>(rec.size());
  r.counters["local_lights_as_sls"] = local ? static_cast<double>(ctx.posed.lights.size()) : 0.0;
  r.counters["shadowed"] = shadowed ? 1.0 : 0.0;
  r.counters["lights"] = lt ? static_cast<double>(ctx.posed.lights.size()) : 0.0;
  r.counters["clamped"] = static_cast<double>(clamped);
  r.bytes = out->value.size() * sizeof(glm::vec3);
  ctx.put<std::shared_ptr<const Shading>>(stage == Stage::Samples ? kSampleRadiance : kDirectShading, out);
}

// Section 5.2: L_S = sum_j L_pj Y_j (eq. 10, the 4 pi/N factor folded into Y_j), then
// L^c_S = L_S * c_S with the SH product (eq. 11), per colour channel.
void pass_intensity(const Settings& s, FrameContext& ctx) {
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& lp = *ctx.get<std::shared_ptr<const Shading>>(kSampleRadiance);
  const int n = s.order, n2 = n * n;
  auto out = std::make_shared<Intensity>();
  out->order = n;
  out->v.assign(pose.size() * 3 * n2, 0.0f);
  tbb::parallel_for(std::size_t{0}, pose.size(), [&](std::size_t i) {
    std::vector<float> ls(3 * n2, 0.0f);
    for (std::size_t k = pose.sample_begin[i]; k < pose.sample_begin[i + 1]; ++k) {
      const float* y = pose.basis[k];
      for (int c = 0; c < 3; ++c)
        for (int q = 0; q < n2; ++q) ls[c * n2 + q] += lp.value[k][c] * y[q];
    }
    for (int c = 0; c < 3; ++c) {
      const std::vector<float> prod = sh::product<float>(n, std::span<const float>(ls.data() + c * n2, n2),
                                                         std::span<const float>(pose.albedo[i] + c * n2, n2));
      std::copy(prod.begin(), prod.end(), out->v.begin() + (i * 3 + c) * n2);
    }
  });
  auto& rec = ctx.record();
  rec.counters["sls"] = static_cast<double>(pose.size());
  rec.bytes = out->v.size() * sizeof(float);
  ctx.put<std::shared_ptr<const Intensity>>(kIntensity, out);
}

void pass_receivers(State& st, const Settings& s, FrameContext& ctx) {
  common::warn_coarse_receivers("spherical_lights", ctx);
  auto r = st.receivers.update("spherical_lights", ctx, s.clusters);
  ctx.record().bytes = r->bytes();
  ctx.put<std::shared_ptr<const Receivers>>(kReceivers, r);
}

// Section 7.3: per receiver cluster, the SLs its receivers sum: its cut of the SL hierarchies with
// the reflection ratios at its central receiver p* (eq. 25), or every leaf.
void pass_cut(const Settings& s, FrameContext& ctx) {
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  auto cuts = std::make_shared<SlCuts>();
  const SlList flat = flat_sl_list(pose);
  const int nc = static_cast<int>(r.clusters.size());
  bool any_tree = false;
  for (const auto& tr : pose.trees) any_tree |= tr != nullptr;
  if (s.hierarchy && any_tree) {
    // The ratios need the intensities on the host (a device backend's copy is read back here).
    const auto& lc = *ctx.get<std::shared_ptr<const Intensity>>(kIntensity);
    cuts->lists.resize(nc);
    cuts->list_of_cluster.resize(nc);
    tbb::parallel_for(0, nc, [&](int c) {
      const ReceiverCluster& rc = r.clusters[c];
      // p* and its normal: the receiver closest to the centroid (paper 004 section 6.3).
      glm::vec3 nstar(0.0f, 1.0f, 0.0f);
      for (std::size_t i = rc.begin; i < rc.end; ++i)
        if (r.soa.px[i] == rc.star.x && r.soa.py[i] == rc.star.y && r.soa.pz[i] == rc.star.z) {
          nstar = glm::vec3(r.soa.nx[i], r.soa.ny[i], r.soa.nz[i]);
          break;
        }
      cuts->lists[c] = sl_cut(s, t, pose, lc, flat, rc.centre, rc.radius, rc.star, nstar);
      cuts->list_of_cluster[c] = c;
    });
  } else {
    cuts->lists.push_back(flat);
    cuts->list_of_cluster.assign(nc, 0);
  }
  double sum = 0.0, parents = 0.0;
  std::size_t mx = 0;
  for (int c = 0; c < nc; ++c) {
    const SlList& l = cuts->lists[cuts->list_of_cluster[c]];
    sum += static_cast<double>(l.sl.size());
    mx = std::max(mx, l.sl.size());
    for (int sl : l.sl) parents += static_cast<std::size_t>(sl) >= pose.leaves;
  }
  auto& rec = ctx.record();
  rec.counters["clusters"] = nc;
  rec.counters["hierarchy"] = s.hierarchy && any_tree;
  rec.counters["cut_mean"] = nc ? sum / nc : 0.0;
  rec.counters["cut_max"] = static_cast<double>(mx);
  rec.counters["parents_in_cuts"] = parents;
  rec.counters["leaf_sls"] = static_cast<double>(pose.leaves);
  rec.bytes = cuts->bytes();
  ctx.put<std::shared_ptr<const SlCuts>>(kSlCuts, cuts);
}

// The SL hierarchies as posed this frame, for make_cut_posed: per SlData object its tree and every
// node's SL sphere; the leaves of objects without a tree are added to every cut.
struct PosedTrees {
  std::vector<const proxies::SphereHierarchy*> trees;
  std::vector<std::vector<scene::Sphere>> node_spheres;
  std::vector<char> has_tree;
  explicit PosedTrees(const SlPose& pose)
      : trees(pose.trees.size(), nullptr), node_spheres(pose.trees.size()), has_tree(pose.trees.size(), 0) {
    for (std::size_t o = 0; o < pose.trees.size(); ++o) {
      if (!pose.trees[o]) continue;
      trees[o] = pose.trees[o].get();
      has_tree[o] = 1;
      for (const int sl : pose.node_sl[o]) node_spheres[o].push_back(scene::Sphere{pose.centre[sl], pose.radius[sl]});
    }
  }
  BlockerList cut(const SlPose& pose, const Tables& t, const CutOptions& opt, const glm::vec3& centre, float radius,
                  const glm::vec3& star, CutStats* stats) const {
    BlockerList l = make_cut_posed(trees, node_spheres, t.log, centre, radius, star, opt, stats);
    for (std::size_t i = 0; i < pose.leaves; ++i)
      if (!has_tree[static_cast<std::size_t>(pose.object[i])]) l.push(pose.centre[i], pose.radius[i], nullptr);
    return l;
  }
};

// The shadow cuts with their sizes in the pass's record.
void put_cuts(FrameContext& ctx, const char* resource, std::shared_ptr<ClusterCuts> cuts, const SlPose& pose) {
  auto& rec = ctx.record();
  rec.counters["clusters"] = static_cast<double>(cuts->list_of_cluster.size());
  rec.counters["cut_mean"] = cuts->mean_size();
  rec.counters["cut_max"] = static_cast<double>(cuts->max_size());
  rec.counters["leaf_sls"] = static_cast<double>(pose.leaves);
  rec.bytes = cuts->bytes();
  ctx.put<std::shared_ptr<const ClusterCuts>>(resource, std::move(cuts));
}

CutOptions shadow_cut_options(const Settings& s) {
  CutOptions opt;
  opt.theta_max = s.theta_max;
  opt.ratio_vectors = true;
  return opt;
}

// Section 7.3: "receiver points far away from an object use a coarser hierarchy level to calculate
// shadows", the cut made "as in [RWS*06]": per receiver cluster, paper 004's cut (eq. 36) of each
// object's SL hierarchy as posed this frame, with the ratio vectors of eq. 37 at its central
// receiver p*; objects without a hierarchy (one SL) give their leaf.
void pass_shadow_cut(const Settings& s, FrameContext& ctx) {
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const PosedTrees posed(pose);
  const CutOptions opt = shadow_cut_options(s);
  const int nc = static_cast<int>(r.clusters.size());
  auto cuts = std::make_shared<ClusterCuts>();
  cuts->lists.resize(nc);
  cuts->list_of_cluster.resize(nc);
  tbb::combinable<CutStats> stats;
  tbb::parallel_for(0, nc, [&](int c) {
    const ReceiverCluster& rc = r.clusters[c];
    cuts->lists[c] = posed.cut(pose, t, opt, rc.centre, rc.radius, rc.star, &stats.local());
    cuts->list_of_cluster[c] = c;
  });
  CutStats total;
  stats.combine_each([&](const CutStats& cs) { total += cs; });
  ctx.record().counters["inner_in_cuts"] = static_cast<double>(total.inner);
  ctx.record().counters["detail_spheres"] = static_cast<double>(total.detail_spheres);
  put_cuts(ctx, kShadowCuts, std::move(cuts), pose);
}

// The first pass's receivers are the SLs' sample points, which have no Lloyd clusters: each
// object's sample points (those of all its SLs, leaves and parents) are one cluster, bounded about
// their centroid, p* the sample point nearest it; its cut as pass_shadow_cut's.
void pass_sample_shadow_cut(const Settings& s, FrameContext& ctx) {
  const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const PosedTrees posed(pose);
  const CutOptions opt = shadow_cut_options(s);
  const std::size_t objects = pose.trees.size();
  std::vector<glm::dvec3> sum(objects, glm::dvec3(0.0));
  std::vector<std::size_t> count(objects, 0);
  const ReceiverSoA& smp = pose.samples;
  auto at = [&](std::size_t k) { return glm::vec3(smp.px[k], smp.py[k], smp.pz[k]); };
  for (std::size_t i = 0; i < pose.size(); ++i) {
    const auto o = static_cast<std::size_t>(pose.object[i]);
    for (std::size_t k = pose.sample_begin[i]; k < pose.sample_begin[i + 1]; ++k) sum[o] += glm::dvec3(at(k));
    count[o] += pose.sample_begin[i + 1] - pose.sample_begin[i];
  }
  std::vector<glm::vec3> centre(objects, glm::vec3(0.0f)), star(objects, glm::vec3(0.0f));
  std::vector<float> radius(objects, 0.0f), nearest(objects, std::numeric_limits<float>::infinity());
  for (std::size_t o = 0; o < objects; ++o)
    if (count[o] > 0) centre[o] = glm::vec3(sum[o] / static_cast<double>(count[o]));
  for (std::size_t i = 0; i < pose.size(); ++i) {
    const auto o = static_cast<std::size_t>(pose.object[i]);
    for (std::size_t k = pose.sample_begin[i]; k < pose.sample_begin[i + 1]; ++k) {
      const float d = glm::length(at(k) - centre[o]);
      radius[o] = std::max(radius[o], d);
      if (d < nearest[o]) {
        nearest[o] = d;
        star[o] = at(k);
      }
    }
  }
  auto cuts = std::make_shared<ClusterCuts>();
  cuts->lists.resize(objects);
  cuts->list_of_cluster.resize(objects);
  tbb::parallel_for(std::size_t(0), objects, [&](std::size_t o) {
    if (count[o] > 0) cuts->lists[o] = posed.cut(pose, t, opt, centre[o], radius[o], star[o], nullptr);
    cuts->list_of_cluster[o] = static_cast<int>(o);
  });
  put_cuts(ctx, kSampleShadowCuts, std::move(cuts), pose);
}

void pass_indirect(const Settings& s, FrameContext& ctx) {
  const auto& pose = *ctx.get<std::shared_ptr<const SlPose>>(kSlPose);
  const auto& lc = *ctx.get<std::shared_ptr<const Intensity>>(kIntensity);
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  auto out = std::make_shared<Shading>();
  out->value.resize(r.soa.size());
  tbb::combinable<IndirectStats> stats;
  const auto t0 = std::chrono::steady_clock::now();
  const int nc = static_cast<int>(r.clusters.size());
  if (s.visibility == IndirectVisibility::RayCast) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.soa.size(), 16), [&](const tbb::blocked_range<std::size_t>& br) {
      accumulate_indirect_ray_cast(s, pose, lc, r.soa, br.begin(), br.end(), out->value.data() + br.begin(), stats.local());
    });
  } else {
    const auto& t = *ctx.get<std::shared_ptr<const Tables>>(kTables);
    const auto& cuts = *ctx.get<std::shared_ptr<const SlCuts>>(kSlCuts);
    tbb::parallel_for(tbb::blocked_range<int>(0, nc, 1), [&](const tbb::blocked_range<int>& cr) {
      for (int c = cr.begin(); c != cr.end(); ++c) {
        const ReceiverCluster& rc = r.clusters[c];
        const SlList& list = cuts.lists[cuts.list_of_cluster[c]];
        tbb::parallel_for(tbb::blocked_range<std::size_t>(rc.begin, rc.end, 32), [&](const tbb::blocked_range<std::size_t>& br) {
          accumulate_indirect(s, t, pose, lc, list, r.soa, br.begin(), br.end(), out->value.data() + br.begin(), stats.local());
        });
      }
    });
  }
  const double secs = common::seconds_since(t0);
  IndirectStats total;
  stats.combine_each([&](const IndirectStats& x) {
    total.lights += x.lights;
    total.eliminated += x.eliminated;
    total.clamped += x.clamped;
    total.exps += x.exps;
    total.exp_flops += x.exp_flops;
    total.rays += x.rays;
  });
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(r.soa.size());
  rec.counters["sls"] = static_cast<double>(pose.size());
  rec.counters["pairs"] = static_cast<double>(total.lights);
  rec.counters["eliminated_pairs"] = static_cast<double>(total.eliminated);
  rec.counters["visibility_clamped"] = static_cast<double>(total.clamped);
  rec.counters["exponentials"] = static_cast<double>(total.exps);
  rec.counters["pairs_per_second"] = secs > 0.0 ? static_cast<double>(total.lights) / secs : 0.0;
  rec.counters["exp_flops"] = total.exp_flops;
  rec.counters["exp_gflops"] = secs > 0.0 ? total.exp_flops / secs * 1e-9 : 0.0;
  rec.counters["per_object_blocking"] = s.blocking == Blocking::PerObject;
  if (s.visibility == IndirectVisibility::RayCast) rec.counters["rays"] = static_cast<double>(total.rays);
  rec.bytes = out->value.size() * sizeof(glm::vec3);
  ctx.put<std::shared_ptr<const Shading>>(kIndirectShading, out);
}

// Per-vertex E/pi through the G-buffer, times the per-pixel albedo (textures keep their detail).
Image vertex_image(FrameContext& ctx, const Shading& sh, const Receivers& r, bool background) {
  const auto& gb = ctx.get<render::GBuffer>(render::kGBuffer);
  std::vector<std::vector<glm::vec3>> per_vertex(ctx.posed.objects.size());
  for (std::size_t o = 0; o < per_vertex.size(); ++o) {
    per_vertex[o].resize(r.index[o].size());
    for (std::size_t v = 0; v < r.index[o].size(); ++v) per_vertex[o][v] = sh.value[r.index[o][v]];
  }
  const render::BackgroundFn bg = background ? render::environment_background(ctx.scene.environment) : render::BackgroundFn{};
  // The G-buffer holds the visibility planes only (gbuffer_planes): albedo and the background's ray
  // directions are derived here, in the one pass over the pixels.
  const render::PinholeCamera cam = render::make_pinhole_camera(ctx.scene, ctx.width, ctx.height, "to_image");
  Image img = render::interpolate_vertex_values(gb, ctx.posed, per_vertex, bg, ctx.pool().image_for_overwrite(gb.width, gb.height),
                                                true, render::DerivedPlanes{&ctx.scene, &cam});
  ctx.record().counters["pixels"] = static_cast<double>(img.rgb.size());
  ctx.record().bytes = img.rgb.size() * sizeof(glm::vec3);
  return img;
}

void pass_to_image(FrameContext& ctx, bool indirect) {
  const auto& r = *ctx.get<std::shared_ptr<const Receivers>>(kReceivers);
  const auto& sh = *ctx.get<std::shared_ptr<const Shading>>(indirect ? kIndirectShading : kDirectShading);
  Image img = vertex_image(ctx, sh, r, !indirect);
  ctx.put<Image>(indirect ? render::kIndirect : render::kDirect, std::move(img));
}

std::vector<render::MemoryItem> memory_items(const scene::Scene& scene, const render::ParamSet& params, int w, int h) {
  using render::MemoryPlace;
  const Settings s = read_settings(params);
  const std::size_t v = render::scene_vertex_count(scene), f = sizeof(float);
  const std::size_t n2 = static_cast<std::size_t>(s.order) * s.order;
  std::vector<render::MemoryItem> m;
  auto host = [&](std::string name, std::size_t bytes, const char* pass, bool transient = false) {
    m.push_back({std::move(name), bytes, MemoryPlace::Host, pass, transient, false, false});
  };
  host(kReceivers, v * (6 * f + sizeof(std::uint32_t)), "receiver_setup");
  host(kLogVisibility, v * n2 * f, "accumulate_log");
  host(kVisibility, v * n2 * f, "exponentiate");
  host(kDirectShading, v * sizeof(glm::vec3), "shade");
  if (s.indirect) host(kIndirectShading, v * sizeof(glm::vec3), "accumulate_indirect");
  host(render::kDirect, 2 * render::image_bytes(w, h), "to_image");
  if (s.indirect) host(render::kIndirect, 2 * render::image_bytes(w, h), "indirect_image");
  return m;
}

common::DeviceKernelRegistry<DeviceKernels>& device_kernels() {
  static common::DeviceKernelRegistry<DeviceKernels> r;
  return r;
}

class SphericalLights final : public render::Technique {
 public:
  std::string name() const override { return "spherical_lights"; }
  render::ShadowBlockers shadow_blockers() const override { return render::ShadowBlockers::SphereProxies; }
  std::string description() const override {
    return "spherical lights (paper 001, Guerrero, Jeschke and Wimmer 2008): proxy spheres as blockers and as SH "
           "secondary lights; shadowed one-bounce diffuse indirect light plus SHEXP-style soft shadows; per-vertex receivers";
  }
  std::vector<ParamDesc> params() const override {
    std::vector<ParamDesc> d;
    // Quality ladder (softgi report): the SH order of every SL quantity, and how finely each SL's
    // emission is sampled (geodesic directions, section 4.2) and projected (strata, section 5.2).
    d.push_back(common::params::order(4, "lighting, visibility, SL intensities and shading (section 7.4: 4)")
                    .with_ladder({"3", "4", "4", "5"}));
    d.push_back(common::params::exp({"hyb", "ol"}, "SH exponential of the visibilities (paper 004 section 4.3)"));
    d.push_back(ParamDesc::choice("blocking", "per_sphere", {"per_sphere", "per_object"},
                                  "order in which SLs block SLs (section 7.2): every SL by distance, or objects by centre distance"));
    d.push_back(ParamDesc::boolean("indirect", true, "one-bounce indirect light from the SLs (off: soft shadows only)"));
    d.push_back(ParamDesc::integer("geodesic_frequency", 3, 1, 16,
                                   "sample directions per SL: geodesic sphere of frequency f, 10 f^2 + 2 vertices (section 4.2: 92, f = 3)")
                    .with_ladder({"1", "2", "3", "4"}));
    d.push_back(ParamDesc::integer("cubemap_resolution", 16, 2, 256, "texels per cube-map face edge of the SL albedo (section 4.2)"));
    d.push_back(ParamDesc::integer("projection_strata", 64, 2, 1024,
                                   "jittered stratified directions of the intensity projection, strata^2 in all (section 5.2, eqs. 9-10)")
                    .with_ladder({"16", "32", "64", "96"}));
    d.push_back(common::params::hierarchy("SL hierarchies cut per receiver cluster with reflection ratios (section 7.3, eqs. 25-26)"));
    d.push_back(ParamDesc::boolean("shadow_hierarchy", false,
                                   "shadows from cuts of the SL hierarchies with paper 004's ratio vectors, per receiver cluster at the "
                                   "vertices and per object at the SLs' sample points (section 7.3, as the paper; needs hierarchy); off: "
                                   "every leaf SL"));
    d.push_back(common::params::theta_max_deg());
    d.push_back(ParamDesc::boolean("reflection_ratios", true, "eq. 25 reflection ratios on the parents of a cut (off: t = 1)"));
    d.push_back(common::params::receiver_clusters());
    d.push_back(common::params::window_h());
    d.push_back(common::params::self_shadow_rules());
    d.push_back(common::params::replacement_rule());
    d.push_back(common::params::table_resolution());
    d.push_back(common::params::log_threshold());
    d.push_back(common::params::analytic_lights());
    d.push_back(ParamDesc::choice("local_lights", "sl", {"sl", "analytic"},
                                  "how the scene's spherical lights shade (with analytic_lights): as SLs of constant intensity "
                                  "under the two-exponential visibility (section 7.3), or by paper 004's light-lobe method"));
    d.push_back(common::params::kernel());
    d.push_back(ParamDesc::choice("indirect_visibility", "sh", {"sh", "ray_cast"},
                                  "receiver pass: average radiance x two-exponential visibility (sh, eqs. 12-24), or a reference "
                                  "that integrates the same SLs exactly with cosine-weighted rays against their spheres (ray_cast; "
                                  "host code on every backend, every leaf SL)"));
    d.push_back(ParamDesc::integer("ray_strata", 64, 2, 256, "ray_cast: strata^2 stratified cosine-weighted rays per receiver"));
    d.push_back(ParamDesc::choice("intersecting", "precomputed", {"precomputed", "run_time"},
                                  "occlusion between intersecting SLs of one object: in the emission, ignored by the receivers "
                                  "(precomputed, section 6.2), or resolved per ray at the receivers (run_time, the paper's future "
                                  "work; needs indirect_visibility=ray_cast)"));
    return d;
  }

  std::vector<render::ExperimentDef> experiments() const override { return spherical_lights::experiments(); }

  std::vector<render::MemoryItem> estimate_memory(const scene::Scene& scene, const render::ParamSet& params, int width,
                                                  int height) const override {
    return memory_items(scene, params, width, height);
  }

  // The images read the visibility planes and derive albedo and the background's ray directions
  // themselves: the other planes, most of the G-buffer's cost at display resolution, are left out.
  unsigned gbuffer_planes(const render::ParamSet&) const override { return render::kGBufferVisibility; }
  render::PassGraph plan(const scene::Scene& scene, const render::ParamSet& params, std::set<std::string>& empty) override {
    const Settings s = read_settings(params);
    render::add_scene_facts(scene, empty);
    if (scene.lights.empty() || !s.lights || s.lights_as_sls) empty.insert(kSphericalLights);
    auto st = state_;
    const auto cpu = render::host_impl;
    const auto kernels = device_kernels().all();
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add_input(render::kMovingObjects);
    common::blocker_spheres_input("spherical_lights", s.indirect ? "shadows and indirect light" : "shadows", scene, kBlockerSpheres, g,
                                  empty);
    g.add_input(kSphericalLights);
    if (!s.indirect) {
      g.add_input(render::kIndirect);
      empty.insert(render::kIndirect);
    }
    render::add_gbuffer_pass(g);
    g.add({"tables", {render::kScene}, {}, {kTables},
           "cap log ZH and OL tables (paper 004 section 6.1), w_theta ZH table (section 6.1, eqs. 16-17)",
           cpu([st, s](FrameContext& c) { pass_tables(*st, s, c); })});
    g.add({"light_tables", {kSphericalLights}, {}, {kLightTables}, "L_H(theta, f) single-lobe ZH table (paper 004 section 7)",
           cpu([st, s](FrameContext& c) { st->light_tables.run_pass(s.order, s.window_h, c, kLightTables); })});
    g.add({"sl_setup", {render::kScene, kBlockerSpheres}, {}, {kSlData},
           "per object, once: segments, sample points, albedo SH and projection sums of its SLs (sections 4.2, 5.2)",
           cpu([st, s](FrameContext& c) { pass_setup(*st, s, c); })});
    g.add({"sl_pose", {kSlData}, {}, {kSlPose}, "this frame's SLs and sample points, soft deformations (section 7.1)",
           cpu([s](FrameContext& c) { pass_pose(s, c); })});
    g.add({"receiver_setup", {render::kScene}, {}, {kReceivers}, "per-vertex receivers of every posed object, Lloyd receiver clusters (section 7.3)",
           cpu([st, s](FrameContext& c) { pass_receivers(*st, s, c); })});
    // Blocker accumulation, exponential and diffuse shading of a stage: the host passes plus each
    // registered backend's kernels.
    auto add_stage = [&](Stage stage, const std::string& suffix, const std::string& what) {
      const char* receivers = stage == Stage::Samples ? kSlPose : kReceivers;
      const bool cut = s.shadow_hierarchy;
      const char* cuts = stage == Stage::Samples ? kSampleShadowCuts : kShadowCuts;
      g.add({"accumulate_log" + suffix, {receivers, kTables, kSlPose}, cut ? std::vector<std::string>{cuts} : std::vector<std::string>{},
             {log_resource(stage)},
             (cut ? "sum of the SL hierarchies' cut as log visibility at the "
                  : "sum of every SL's log visibility at the ") +
                 what + " (eqs. 6-7; paper 004 eq. 34, rules of section 6.2)",
             common::with_kernels<DeviceKernels>(cpu([s, stage](FrameContext& c) { pass_accumulate(s, c, stage); }), kernels,
                                                 [s, stage](const DeviceKernels& k) -> render::PassFn {
                                                   if (!k.accumulate) return {};
                                                   return [s, stage, f = k.accumulate](FrameContext& c) { f(s, c, stage); };
                                                 })});
      g.add({"exponentiate" + suffix, {receivers, kTables, log_resource(stage)}, {}, {visibility_resource(stage)},
             "SH exponential of the summed logs at the " + what + " (paper 004 section 4)",
             common::with_kernels<DeviceKernels>(cpu([s, stage](FrameContext& c) { pass_exponentiate(s, c, stage); }), kernels,
                                                 [s, stage](const DeviceKernels& k) -> render::PassFn {
                                                   if (!k.exponentiate) return {};
                                                   return [s, stage, f = k.exponentiate](FrameContext& c) { f(s, c, stage); };
                                                 })});
      g.add({stage == Stage::Samples ? "sample_shading" : "shade", {receivers, kTables}, {visibility_resource(stage), kLightTables, kSlPose},
             {stage == Stage::Samples ? kSampleRadiance : kDirectShading},
             stage == Stage::Samples ? "diffuse reflection at every SL sample point under the SLs' shadows (section 5.1, eqs. 3-8)"
                                     : "direct light: L_H(N) . g per vertex, environment and analytic lights",
             common::with_kernels<DeviceKernels>(cpu([st, s, stage](FrameContext& c) { pass_shade(*st, s, c, stage, nullptr); }), kernels,
                                                 [st, s, stage](const DeviceKernels& k) -> render::PassFn {
                                                   if (!k.shade) return {};
                                                   return [st, s, stage, f = k.shade](FrameContext& c) { pass_shade(*st, s, c, stage, &f); };
                                                 })});
    };
    if (s.shadow_hierarchy)
      g.add({"shadow_cut", {kReceivers, kTables, kSlPose}, {}, {kShadowCuts},
             "per receiver cluster: cut of the SL hierarchies for the shadows (section 7.3; paper 004 eqs. 36-37)",
             cpu([s](FrameContext& c) { pass_shadow_cut(s, c); })});
    add_stage(Stage::Receivers, "", "vertices");
    g.add({"to_image", {render::kGBuffer, kReceivers, kDirectShading}, {}, {render::kDirect}, "per-vertex direct radiance through the G-buffer",
           cpu([](FrameContext& c) { pass_to_image(c, false); })});
    if (s.indirect) {
      if (s.shadow_hierarchy)
        g.add({"sample_shadow_cut", {kTables, kSlPose}, {}, {kSampleShadowCuts},
               "per object: cut of the SL hierarchies for its sample points' shadows (section 7.3; paper 004 eqs. 36-37)",
               cpu([s](FrameContext& c) { pass_sample_shadow_cut(s, c); })});
      add_stage(Stage::Samples, "_samples", "SL sample points");
      g.add({"intensity_update", {kSlPose, kSampleRadiance}, {}, {kIntensity},
             "SL intensities: Voronoi-cell projection sums (eq. 10) times the albedo SH (eq. 11)",
             common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_intensity(s, c); }), kernels,
                                                 [s](const DeviceKernels& k) -> render::PassFn {
                                                   if (!k.intensity) return {};
                                                   return [s, f = k.intensity](FrameContext& c) { f(s, c); };
                                                 })});
      if (s.visibility == IndirectVisibility::RayCast) {
        g.add({"accumulate_indirect", {kReceivers, kSlPose, kIntensity}, {}, {kIndirectShading},
               std::string("reference: every leaf SL integrated by ") + std::to_string(s.ray_strata * s.ray_strata) +
                   " cosine-weighted rays per receiver against the SL spheres, intersecting SLs' occlusion " +
                   (s.pre.intersecting == IntersectingOcclusion::RunTime ? "at run time" : "precomputed (section 6.2)"),
               cpu([s](FrameContext& c) { pass_indirect(s, c); })});
      } else {
        g.add({"sl_cut", {kReceivers, kTables, kSlPose, kIntensity}, {}, {kSlCuts},
               s.hierarchy ? "per receiver cluster: cut of the SL hierarchies (paper 004 eq. 36), reflection ratios (eq. 25)"
                           : "every leaf SL for every receiver cluster",
               cpu([s](FrameContext& c) { pass_cut(s, c); })});
        g.add({"accumulate_indirect", {kReceivers, kTables, kSlPose, kIntensity, kSlCuts}, {}, {kIndirectShading},
               std::string("average radiance x average visibility per SL (eqs. 14-24), ") +
                   (s.blocking == Blocking::PerObject ? "per-object" : "per-sphere") + " blocking (section 7.2)",
               common::with_kernels<DeviceKernels>(cpu([s](FrameContext& c) { pass_indirect(s, c); }), kernels,
                                                   [s](const DeviceKernels& k) -> render::PassFn {
                                                     if (!k.indirect) return {};
                                                     return [s, f = k.indirect](FrameContext& c) { f(s, c); };
                                                   })});
      }
      g.add({"indirect_image", {render::kGBuffer, kReceivers, kIndirectShading}, {}, {render::kIndirect},
             "per-vertex indirect radiance through the G-buffer", cpu([](FrameContext& c) { pass_to_image(c, true); })});
    }
    render::add_compose_pass(g);
    return g;
  }

 private:
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

}  // namespace

std::unique_ptr<render::Technique> create() { return std::make_unique<SphericalLights>(); }

void register_device_kernels(const std::string& backend, DeviceKernels kernels) { device_kernels().add(backend, std::move(kernels)); }

}  // namespace softgi::techniques::spherical_lights
