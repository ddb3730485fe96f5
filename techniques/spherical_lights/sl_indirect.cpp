// The receiver accumulation of spherical lights (paper 001 section 6): average radiance times
// average visibility per SL, summed over the SLs (eqs. 13-24), in per-sphere or per-object blocking
// order (section 7.2). Citations resolve in docs/papers.md.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "sl_passes.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::techniques::spherical_lights {

namespace {

// Floating-point operations of one SH square and one SH product as ProductPlan evaluates them (a
// square term v f_j f_k: 2; an off-diagonal product term v (f_j g_k + f_k g_j): 4; a diagonal one: 2).
double square_flops(const ProductPlan& p) { return 2.0 * static_cast<double>(p.sq_v.size()); }
double product_flops(const ProductPlan& p) {
  double f = 0.0;
  for (std::size_t i = 0; i + 1 < p.pr_begin.size(); ++i)
    f += 4.0 * (p.pr_offdiag_end[i] - p.pr_begin[i]) + 2.0 * (p.pr_begin[i + 1] - p.pr_offdiag_end[i]);
  return f;
}

// rho_N of eq. 24 in SH: the clamped cosine about n over pi (E/pi per unit radiance), n^2 floats.
// Its band factors are the same for every receiver: computed once per order, for the clamped
// cosine's quadrature takes a lock and allocates (per receiver, on every thread at once).
std::array<float, sh::kMaxCoeffs> brdf_vector(int order, const glm::vec3& n) {
  static const auto band_factor = [] {
    std::array<std::array<float, sh::kMaxOrder>, sh::kMaxOrder + 1> f{};
    for (int o = 1; o <= sh::kMaxOrder; ++o) {
      const std::vector<double> cc = sh::clamped_cosine_zh(o);
      for (int l = 0; l < o; ++l) f[o][l] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
    }
    return f;
  }();
  std::array<float, sh::kMaxCoeffs> hn{};
  sh::eval_basis(order, sh::Vec3<float>{n.x, n.y, n.z}, hn.data());
  for (int l = 0; l < order; ++l)
    for (int mm = -l; mm <= l; ++mm) hn[sh::index(l, mm)] *= band_factor[order][l];
  return hn;
}

// The batched SH exponentials by the technique's method and order.
BatchExp batch_exp(const Settings& s, const Tables& t) {
  BatchExp be;
  be.order = s.order;
  be.method = s.exp;
  be.tables = t.sh.get();
  be.plan = &ProductPlan::get(s.order);
  return be;
}

// The SH exponentials of `count` log vectors f into g (receiver-major, order^2 each) by the
// technique's method; returns their squares and products.
sh::ExpStats exponentiate(const Settings& s, const Tables& t, const float* f, float* g, std::size_t count) {
  sh::ExpStats es;
  exp_batch(s.isa, batch_exp(s, t), f, g, count, 0, es);
  return es;
}

// Eqs. 23-24: rho_N . (exp(S) - exp(S + G)) for the exponentials e0 = exp(S), e1 = exp(S + G).
float pair_visibility(const float* e0, const float* e1, const std::array<float, sh::kMaxCoeffs>& hn, int n2) {
  float v = 0.0f;
  for (int q = 0; q < n2; ++q) v += (e0[q] - e1[q]) * hn[q];
  return v;
}

struct Scratch {
  // The list's spheres for sphere_fan, made once per list: centres, radii, flat SL indices.
  std::vector<float> cx, cy, cz, r;
  std::vector<int> id;
  common::SphereFan fan;
  BatchExp be;
  std::vector<float> G;           // per SL: log vector of its (rule-adjusted) sphere, n^2
  std::vector<float> key;         // per SL: distance from p to its adjusted sphere
  std::vector<std::uint8_t> alive;
  std::vector<float> rgb;         // per SL: its average radiance towards p (eqs. 16-18)
  std::vector<int> active, order, position;
  std::vector<float> f, g;        // the active SLs' log vectors S and S + G, and their exponentials
  std::vector<std::size_t> e0, e1;  // per active SL: which of them are its S and S + G
  std::vector<float> prefix;
  std::vector<float> object_distance;  // per object: distance of its centre from p (per-object blocking)
};

// Scratch for the receivers of one SL list.
void prepare(Scratch& sc, const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& list) {
  const int order = s.order;
  if (t.log.order != order || t.weight.order != order || lc.order != order)
    throw std::logic_error("spherical_lights accumulate_indirect: tables or intensities of another order than " + std::to_string(order));
  const std::size_t n2 = static_cast<std::size_t>(order) * order;
  if (pose.rotation.size() != pose.size() || lc.v.size() < pose.size() * 3 * n2)
    throw std::logic_error("spherical_lights accumulate_indirect: " + std::to_string(pose.size()) + " SLs with " +
                           std::to_string(pose.rotation.size()) + " rotations and " + std::to_string(lc.v.size()) + " intensity floats");
  const std::size_t m = list.sl.size();
  sc.cx.resize(m);
  sc.cy.resize(m);
  sc.cz.resize(m);
  sc.r.resize(m);
  sc.id.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    const int slk = list.sl[k];
    if (slk < 0 || static_cast<std::size_t>(slk) >= pose.size())
      throw std::logic_error("spherical_lights accumulate_indirect: SL list entry " + std::to_string(slk) + " outside the " +
                             std::to_string(pose.size()) + " SLs");
    sc.cx[k] = pose.centre[slk].x;
    sc.cy[k] = pose.centre[slk].y;
    sc.cz[k] = pose.centre[slk].z;
    sc.r[k] = pose.radius[slk];
    sc.id[k] = slk;
  }
  static_assert(sizeof(glm::mat3) == 9 * sizeof(float), "sphere_fan reads rotations as 9 packed floats");
  sc.fan = {};
  sc.fan.cx = sc.cx.data();
  sc.fan.cy = sc.cy.data();
  sc.fan.cz = sc.cz.data();
  sc.fan.r = sc.r.data();
  sc.fan.count = m;
  sc.fan.id = sc.id.data();
  sc.fan.L = lc.v.data();
  sc.fan.rot = pose.rotation.empty() ? nullptr : &pose.rotation[0][0][0];
  sc.fan.weight = t.weight.w.data();
  sc.fan.weight_rows = t.weight.rows;
  sc.G.resize(m * n2);
  sc.key.resize(m);
  sc.alive.resize(m);
  sc.rgb.resize(3 * m);
  sc.be = batch_exp(s, t);
}

// Fills vbar / lbar for every SL at receiver (p, n). Returns nothing for an SL the rules eliminate
// (vbar 0): it neither blocks nor lights p. `sc` was prepared for `list`.
void receiver_terms(const Settings& s, const Tables& t, const SlPose& pose, const SlList& list, const glm::vec3& p,
                    const glm::vec3& n, Scratch& sc, std::vector<float>& vbar, std::vector<glm::vec3>& lbar, IndirectStats& st) {
  const int order = s.order, n2 = order * order;
  const std::size_t m = list.sl.size();
  sc.position.assign(m, -1);
  sc.active.clear();
  vbar.assign(m, 0.0f);
  lbar.assign(m, glm::vec3(0.0f));
  if (m == 0) return;
  const std::array<float, sh::kMaxCoeffs> hn = brdf_vector(order, n);
  // Per SL, a lane each: the replacement rules of paper 004 section 6.2 (section 6.2 of paper 001,
  // receiver points inside SLs, shared with SHEXP), the adjusted sphere's log vector and distance,
  // and the average radiance (eqs. 16-18) over the SL itself, whose intensity is defined on its own
  // sphere: theta and the direction of p from its centre, rotated into the SL's rest frame (section
  // 7.1: w_theta rotated by the inverse rotation). A receiver inside the SL sees it at theta = pi/2.
  common::sphere_fan(s.isa, t.log, s.rule, p, n, sc.fan, sc.G.data(), sc.key.data(), sc.alive.data(), sc.rgb.data());
  for (std::size_t k = 0; k < m; ++k) {
    if (!sc.alive[k]) {
      ++st.eliminated;
      continue;
    }
    const glm::vec3 acc(sc.rgb[3 * k], sc.rgb[3 * k + 1], sc.rgb[3 * k + 2]);
    // Eq. 26: a parent of the hierarchy scaled by its reflection ratio.
    lbar[k] = list.ratio.empty() ? acc : acc * list.ratio[k];
    sc.active.push_back(static_cast<int>(k));
  }
  if (sc.active.empty()) return;

  // Section 7.2: per-sphere blocking orders every SL by its distance from p; per-object blocking
  // orders objects by the distance of their centres (the paper's object-centre sorting) and the SLs
  // of an object by distance. Either way an SL is darkened by every SL before it except the
  // intersecting ones of its own object, so the two differ only in the order (prefix sums below).
  // Ties keep the list's order: sc.active is ascending, so the index as the last key gives what a
  // stable sort would, without the temporary buffer std::stable_sort allocates per call.
  sc.order = sc.active;
  if (s.blocking == Blocking::PerSphere) {
    std::sort(sc.order.begin(), sc.order.end(), [&](int a, int b) { return sc.key[a] != sc.key[b] ? sc.key[a] < sc.key[b] : a < b; });
  } else {
    std::vector<float>& od = sc.object_distance;
    od.resize(pose.object_centre.size());
    for (std::size_t o = 0; o < od.size(); ++o) od[o] = glm::length(pose.object_centre[o] - p);
    std::sort(sc.order.begin(), sc.order.end(), [&](int a, int b) {
      const int oa = pose.object[list.sl[a]], ob = pose.object[list.sl[b]];
      const float da = od[oa], db = od[ob];
      if (da != db) return da < db;
      if (oa != ob) return oa < ob;
      if (sc.key[a] != sc.key[b]) return sc.key[a] < sc.key[b];
      return a < b;
    });
  }
  const std::size_t na = sc.order.size();
  for (std::size_t a = 0; a < na; ++a) sc.position[sc.order[a]] = static_cast<int>(a);
  sc.f.resize(2 * na * n2);
  sc.g.resize(2 * na * n2);
  sc.e0.resize(na);
  sc.e1.resize(na);
  sc.prefix.assign(n2, 0.0f);
  // exp(S_i) of an SL that no intersecting SL before it reduces is exp(S + G) of the SL before it
  // when that one had none either: S_{a+1} is then the prefix sum itself, formed by the same float
  // additions as S_a + G_a, so the exponential is taken once and read twice (bit for bit the same).
  std::size_t nf = 0;
  bool prev_plain = false;
  const int* position = sc.position.data();
  for (std::size_t a = 0; a < na; ++a) {
    const int i = sc.order[a];
    // Eq. 21: intersecting SLs of S_i's own object are not its blockers (their occlusion is in its
    // emission, section 4.2 rule 2).
    bool plain = true;
    for (int j : list.intersecting[i])
      if (position[j] >= 0 && position[j] < static_cast<int>(a)) {
        plain = false;
        break;
      }
    float* S;
    if (plain && prev_plain) {
      sc.e0[a] = sc.e1[a - 1];
      S = sc.f.data() + sc.e1[a - 1] * n2;
    } else {
      sc.e0[a] = nf;
      S = sc.f.data() + nf++ * n2;
      for (int q = 0; q < n2; ++q) S[q] = sc.prefix[q];
      if (!plain)
        for (int j : list.intersecting[i])
          if (position[j] >= 0 && position[j] < static_cast<int>(a))
            for (int q = 0; q < n2; ++q) S[q] -= sc.G[j * n2 + q];
    }
    sc.e1[a] = nf;
    float* SG = sc.f.data() + nf++ * n2;
    const float* Gi = sc.G.data() + i * n2;
    for (int q = 0; q < n2; ++q) {
      SG[q] = S[q] + Gi[q];
      sc.prefix[q] += Gi[q];
    }
    prev_plain = plain;
  }
  sh::ExpStats es;
  exp_batch(s.isa, sc.be, sc.f.data(), sc.g.data(), nf, 0, es);
  const ProductPlan& plan = *sc.be.plan;
  st.exps += static_cast<long long>(nf);
  st.exp_flops += es.squares * square_flops(plan) + es.products * product_flops(plan);
  // Eq. 23: V = exp(S) - exp(S + G_i), the part of S_i's cap no closer SL covers; eq. 24: dotted
  // with the BRDF vector.
  for (std::size_t a = 0; a < na; ++a) {
    const int i = sc.order[a];
    float v = pair_visibility(sc.g.data() + sc.e0[a] * n2, sc.g.data() + sc.e1[a] * n2, hn, n2);
    if (v < 0.0f) {
      // SH ringing of the two exponentials; a visibility is never negative.
      v = 0.0f;
      ++st.clamped;
    }
    vbar[i] = v;
    ++st.lights;
  }
}

}  // namespace

namespace {

// Section 7.3's local lights over receivers k < count, pn(k) giving (p, n): the term of each added
// to out[k]. The receivers' exponentials are taken in one batch and the lists' storage is reused
// across receivers; the sort moves spheres, and log vectors are made only for the spheres before
// the farthest light. Per receiver the floats are those of the definition in sl_passes.hpp.
template <class PN>
void local_lights_run(const Settings& s, const Tables& t, const SlPose* pose, const std::vector<scene::SphericalLight>& lights,
                      std::size_t count, PN pn, glm::vec3* out) {
  const int order = s.order, n2 = order * order;
  if (lights.empty() || count == 0) return;
  // Every leaf SL and every light, rule-adjusted, by distance from p: a light is darkened by every
  // sphere before it (eq. 23; lights belong to no object, so nothing is left out).
  struct Entry {
    float key;
    int light;  // -1: a leaf SL (a blocker only)
    glm::vec3 centre;
    float radius;
  };
  struct Pair {
    std::size_t receiver;
    int light;
  };
  std::vector<Entry> e;
  std::vector<float> f, g, prefix(static_cast<std::size_t>(n2)), G(static_cast<std::size_t>(n2));
  std::vector<Pair> pairs;
  std::vector<std::array<float, sh::kMaxCoeffs>> hn;
  const std::size_t leaves = pose ? pose->leaves : 0;
  for (std::size_t k = 0; k < count; ++k) {
    const auto [p, n] = pn(k);
    if (!(glm::dot(n, n) > 0.0f)) continue;
    e.clear();
    auto add = [&](const glm::vec3& c, float r, int light) {
      const AdjustedSphere adj = apply_replacement_rule(s.rule, p, n, c, r);
      const float dist = glm::length(adj.center - p);
      if (!(adj.radius > 0.0f) || !(dist > adj.radius)) return;
      e.push_back(Entry{dist - adj.radius, light, adj.center, adj.radius});
    };
    for (std::size_t i = 0; i < leaves; ++i) add(pose->centre[i], pose->radius[i], -1);
    for (std::size_t j = 0; j < lights.size(); ++j) add(lights[j].position, lights[j].radius, static_cast<int>(j));
    std::stable_sort(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.key < b.key; });
    // Spheres past the farthest light darken nothing: their log vectors are not needed.
    std::size_t last = e.size();
    while (last > 0 && e[last - 1].light < 0) --last;
    if (last == 0) continue;
    hn.push_back(brdf_vector(order, n));
    std::fill(prefix.begin(), prefix.end(), 0.0f);
    for (std::size_t a = 0; a < last; ++a) {
      sphere_zh_vector(t.log, p, e[a].centre, e[a].radius, nullptr, G.data());
      if (e[a].light >= 0) {
        pairs.push_back(Pair{k, e[a].light});
        f.insert(f.end(), prefix.begin(), prefix.end());
        for (int q = 0; q < n2; ++q) f.push_back(prefix[q] + G[q]);
      }
      for (int q = 0; q < n2; ++q) prefix[q] += G[q];
    }
  }
  if (pairs.empty()) return;
  g.resize(f.size());
  exponentiate(s, t, f.data(), g.data(), 2 * pairs.size());
  // Per receiver, its lights' terms summed from zero in list order, then added to out.
  std::size_t h = 0;
  for (std::size_t a = 0; a < pairs.size();) {
    const std::size_t k = pairs[a].receiver;
    glm::vec3 term(0.0f);
    for (; a < pairs.size() && pairs[a].receiver == k; ++a) {
      const float* e0 = g.data() + 2 * a * n2;
      const float v = pair_visibility(e0, e0 + n2, hn[h], n2);
      // A light's surface emits its radiance uniformly: its average radiance (eq. 16) is that radiance.
      term += std::max(v, 0.0f) * lights[pairs[a].light].radiance;
    }
    out[k] += term;
    ++h;
  }
}

}  // namespace

glm::vec3 local_lights_term(const Settings& s, const Tables& t, const SlPose* pose, const std::vector<scene::SphericalLight>& lights,
                            const glm::vec3& p, const glm::vec3& n) {
  glm::vec3 out(0.0f);
  local_lights_run(s, t, pose, lights, 1, [&](std::size_t) { return std::pair<glm::vec3, glm::vec3>(p, n); }, &out);
  return out;
}

void add_local_lights(const Settings& s, const Tables& t, const SlPose* pose, const std::vector<scene::SphericalLight>& lights,
                      const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out) {
  local_lights_run(s, t, pose, lights, end - begin, [&](std::size_t k) {
    const std::size_t i = begin + k;
    return std::pair<glm::vec3, glm::vec3>(glm::vec3(rec.px[i], rec.py[i], rec.pz[i]), glm::vec3(rec.nx[i], rec.ny[i], rec.nz[i]));
  }, out);
}

namespace {

// A 32-bit integer hash (Wellons' lowbias32) for the per-receiver jitter: the same receiver gets the
// same rays on every backend and every run.
std::uint32_t hash32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}
float unit_float(std::uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }

// Nearest positive distance along unit d from p to the sphere (c, r), or -1. `from_inside`: p may be
// inside, then the exit distance.
float ray_sphere(const glm::vec3& p, const glm::vec3& d, const glm::vec3& c, float r, bool from_inside) {
  const glm::vec3 oc = p - c;
  const float b = glm::dot(oc, d), q = glm::dot(oc, oc) - r * r;
  const float disc = b * b - q;
  if (disc < 0.0f) return -1.0f;
  const float root = std::sqrt(disc);
  if (q > 0.0f) {
    const float t = -b - root;
    return t > 0.0f ? t : -1.0f;
  }
  return from_inside ? -b + root : -1.0f;
}

}  // namespace

void accumulate_indirect_ray_cast(const Settings& s, const SlPose& pose, const Intensity& lc, const ReceiverSoA& rec, std::size_t begin,
                                  std::size_t end, glm::vec3* out, IndirectStats& st) {
  const int order = lc.order, n2 = order * order;
  const int strata = s.ray_strata, rays = strata * strata;
  const bool run_time = s.pre.intersecting == IntersectingOcclusion::RunTime;
  struct Active {
    int sl;
    glm::vec3 centre;  // rule-adjusted sphere: what the rays are tested against
    float radius;
  };
  struct Hit {
    int a;  // index into `active`
    float t;
  };
  std::vector<Active> active;
  std::vector<Hit> hits;
  std::array<float, sh::kMaxCoeffs> y{};
  for (std::size_t r = begin; r < end; ++r) {
    const glm::vec3 p(rec.px[r], rec.py[r], rec.pz[r]), n(rec.nx[r], rec.ny[r], rec.nz[r]);
    out[r - begin] = glm::vec3(0.0f);
    if (!(glm::dot(n, n) > 0.0f)) continue;
    active.clear();
    for (std::size_t i = 0; i < pose.leaves; ++i) {
      // The rules and the elimination test of the Sh pass (receiver_terms), so the two differ only
      // in how the light of the SLs they keep is integrated.
      const AdjustedSphere adj = apply_replacement_rule(s.rule, p, n, pose.centre[i], pose.radius[i]);
      const float dist = glm::length(adj.center - p);
      if (!(adj.radius > 0.0f) || !(dist > adj.radius)) {
        ++st.eliminated;
        continue;
      }
      active.push_back({static_cast<int>(i), adj.center, adj.radius});
    }
    st.lights += static_cast<long long>(active.size());
    if (active.empty()) continue;
    // A frame about N for the cosine-weighted directions (pdf cos / pi: E/pi is their mean radiance).
    const glm::vec3 a = std::abs(n.x) < 0.9f ? glm::vec3(1.0f, 0.0f, 0.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
    const glm::vec3 tx = glm::normalize(glm::cross(a, n)), ty = glm::cross(n, tx);
    const std::uint32_t seed = hash32(static_cast<std::uint32_t>(r) * 0x9e3779b9u + 0x632be5abu);
    glm::vec3 sum(0.0f);
    for (int k = 0; k < rays; ++k) {
      const std::uint32_t h = hash32(seed ^ static_cast<std::uint32_t>(k) * 0x85ebca6bu);
      const float u1 = (static_cast<float>(k / strata) + unit_float(h)) / static_cast<float>(strata);
      const float u2 = (static_cast<float>(k % strata) + unit_float(hash32(h))) / static_cast<float>(strata);
      // Shirley and Chiu's concentric map of the stratum to the unit disc (area-preserving and far
      // less distorting than polar coordinates, so fewer strata straddle a cap's rim), lifted to the
      // hemisphere (Malley's method: cosine-weighted).
      const float sx = 2.0f * u1 - 1.0f, sy = 2.0f * u2 - 1.0f;
      float rad = 0.0f, phi = 0.0f;
      const float quarter = static_cast<float>(sh::kPi) / 4.0f;
      if (sx != 0.0f || sy != 0.0f) {
        if (std::abs(sx) > std::abs(sy)) {
          rad = sx;
          phi = quarter * (sy / sx);
        } else {
          rad = sy;
          phi = 2.0f * quarter - quarter * (sx / sy);
        }
      }
      const float dx = rad * std::cos(phi), dy = rad * std::sin(phi);
      const glm::vec3 d = dx * tx + dy * ty + std::sqrt(std::max(0.0f, 1.0f - dx * dx - dy * dy)) * n;
      hits.clear();
      for (std::size_t q = 0; q < active.size(); ++q) {
        const float t = ray_sphere(p, d, active[q].centre, active[q].radius, false);
        if (t > 0.0f) hits.push_back({static_cast<int>(q), t});
      }
      if (hits.empty()) continue;
      std::size_t first = 0, last = hits.size();
      if (run_time) {
        // Only the nearest SL the ray hits is seen.
        for (std::size_t q = 1; q < hits.size(); ++q)
          if (hits[q].t < hits[first].t) first = q;
        last = first + 1;
      }
      for (std::size_t hq = first; hq < last; ++hq) {
        const Hit& hh = hits[hq];
        const int i = active[hh.a].sl;
        if (!run_time) {
          // Section 6.2: S_i counts unless an SL in front of it that is not one of its own
          // object's intersecting SLs covers this direction.
          bool blocked = false;
          for (const Hit& g : hits)
            if (g.t < hh.t && g.a != hh.a) {
              const auto& x = pose.intersecting[i];
              if (std::find(x.begin(), x.end(), active[g.a].sl) == x.end()) {
                blocked = true;
                break;
              }
            }
          if (blocked) continue;
        }
        // The radiance leaving the SL's own sphere where this ray sees it (its intensity is defined
        // on that sphere); where the adjusted sphere pokes out of it, the adjusted hit's normal.
        const glm::vec3 c = pose.centre[i];
        float t = ray_sphere(p, d, c, pose.radius[i], true);
        glm::vec3 m = t > 0.0f ? (p + t * d - c) : (p + hh.t * d - active[hh.a].centre);
        const float ml = glm::length(m);
        m = ml > 0.0f ? m / ml : n;
        const glm::vec3 dl = glm::transpose(pose.rotation[i]) * m;
        sh::eval_basis(order, sh::Vec3<float>{dl.x, dl.y, dl.z}, y.data());
        const float* L = lc.v.data() + static_cast<std::size_t>(i) * 3 * n2;
        glm::vec3 rad3(0.0f);
        for (int q = 0; q < n2; ++q) rad3 += y[q] * glm::vec3(L[q], L[n2 + q], L[2 * n2 + q]);
        sum += rad3;
      }
    }
    st.rays += rays;
    out[r - begin] = glm::max(sum / static_cast<float>(rays), glm::vec3(0.0f));
  }
}

SlList flat_sl_list(const SlPose& pose) {
  SlList l;
  l.sl.resize(pose.leaves);
  l.intersecting.resize(pose.leaves);
  for (std::size_t i = 0; i < pose.leaves; ++i) {
    l.sl[i] = static_cast<int>(i);
    l.intersecting[i] = pose.intersecting[i];  // leaves' flat indices are their entries
  }
  return l;
}

std::size_t SlCuts::bytes() const {
  std::size_t b = list_of_cluster.size() * sizeof(int);
  for (const auto& l : lists) {
    b += l.sl.size() * (sizeof(int) + sizeof(glm::vec3));
    for (const auto& x : l.intersecting) b += x.size() * sizeof(int);
  }
  return b;
}

void accumulate_indirect(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& list,
                         const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out, IndirectStats& stats) {
  Scratch sc;
  prepare(sc, s, t, pose, lc, list);
  std::vector<float> vbar;
  std::vector<glm::vec3> lbar;
  for (std::size_t r = begin; r < end; ++r) {
    const glm::vec3 p(rec.px[r], rec.py[r], rec.pz[r]), n(rec.nx[r], rec.ny[r], rec.nz[r]);
    glm::vec3 e(0.0f);
    if (glm::dot(n, n) > 0.0f) {
      receiver_terms(s, t, pose, list, p, n, sc, vbar, lbar, stats);
      for (std::size_t i = 0; i < vbar.size(); ++i) e += lbar[i] * vbar[i];
    }
    out[r - begin] = glm::max(e, glm::vec3(0.0f));
  }
}

void indirect_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& list, const glm::vec3& p,
                    const glm::vec3& n, std::vector<float>& vbar, std::vector<glm::vec3>& lbar) {
  Scratch sc;
  prepare(sc, s, t, pose, lc, list);
  IndirectStats st;
  receiver_terms(s, t, pose, list, p, n, sc, vbar, lbar, st);
}

void indirect_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const glm::vec3& p,
                    const glm::vec3& n, std::vector<float>& vbar, std::vector<glm::vec3>& lbar) {
  indirect_terms(s, t, pose, lc, flat_sl_list(pose), p, n, vbar, lbar);
}

SlList sl_cut(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& flat, const glm::vec3& pR,
              float rR, const glm::vec3& pstar, const glm::vec3& nstar) {
  SlList cut;
  const double sin_max = std::sin(s.theta_max);
  std::vector<int> stack;
  for (std::size_t o = 0; o < pose.trees.size(); ++o) {
    const proxies::SphereHierarchy* tree = pose.trees[o].get();
    if (!tree) {
      for (std::size_t i = 0; i < pose.leaves; ++i)
        if (pose.object[i] == static_cast<int>(o)) cut.sl.push_back(static_cast<int>(i));
      continue;
    }
    stack.assign(1, tree->root());
    while (!stack.empty()) {
      const int id = stack.back();
      stack.pop_back();
      const proxies::SphereNode& node = tree->nodes()[id];
      const int sl = pose.node_sl[o][id];
      // Paper 004 eq. 36: the node subtends less than theta_max over the whole receiver cluster.
      const bool small = pose.radius[sl] < sin_max * (glm::length(pose.centre[sl] - pR) - rR);
      if (!node.children.empty() && !small) {
        for (int ch : node.children) stack.push_back(ch);
        continue;
      }
      cut.sl.push_back(sl);
    }
  }
  // Section 6.2 at run time: within an object, entries whose spheres intersect do not block each
  // other (for two leaves, the precomputed lists; a parent's own emission excludes what its
  // segment's neighbours cover).
  cut.intersecting.resize(cut.sl.size());
  for (std::size_t a = 0; a < cut.sl.size(); ++a)
    for (std::size_t b = 0; b < cut.sl.size(); ++b) {
      const int i = cut.sl[a], j = cut.sl[b];
      if (a == b || pose.object[i] != pose.object[j]) continue;
      const bool leaves = static_cast<std::size_t>(i) < pose.leaves && static_cast<std::size_t>(j) < pose.leaves;
      const bool hit = leaves ? std::find(pose.intersecting[i].begin(), pose.intersecting[i].end(), j) != pose.intersecting[i].end()
                              : glm::length(pose.centre[i] - pose.centre[j]) < pose.radius[i] + pose.radius[j];
      if (hit) cut.intersecting[a].push_back(static_cast<int>(b));
    }
  // Eq. 25 at the cluster's central receiver.
  cut.ratio.assign(cut.sl.size(), glm::vec3(1.0f));
  bool parents = false;
  for (int sl : cut.sl) parents |= static_cast<std::size_t>(sl) >= pose.leaves;
  if (!parents || !s.reflection_ratios) return cut;
  std::vector<float> vf, vc;
  std::vector<glm::vec3> lf, lcut;
  indirect_terms(s, t, pose, lc, flat, pstar, nstar, vf, lf);
  indirect_terms(s, t, pose, lc, cut, pstar, nstar, vc, lcut);
  for (std::size_t a = 0; a < cut.sl.size(); ++a) {
    const int sl = cut.sl[a];
    if (static_cast<std::size_t>(sl) < pose.leaves) continue;
    glm::vec3 num(0.0f);
    for (int leaf : pose.leaves_below[sl]) num += lf[leaf] * vf[leaf];
    const glm::vec3 den = lcut[a] * vc[a];
    for (int c = 0; c < 3; ++c) {
      // A parent that contributes nothing at p* keeps ratio 1; the clamp bounds what one central
      // receiver's ratio can do to the rest of its cluster.
      const float scale = std::max(std::abs(num[c]), std::abs(den[c]));
      cut.ratio[a][c] = den[c] > 1e-6f * scale && den[c] > 1e-12f ? std::clamp(num[c] / den[c], 0.0f, kMaxReflectionRatio) : 1.0f;
    }
  }
  return cut;
}

}  // namespace softgi::techniques::spherical_lights
