// The receiver accumulation of spherical lights (paper 001 section 6): average radiance times
// average visibility per SL, summed over the SLs (eqs. 13-24), in per-sphere or per-object blocking
// order (section 7.2). Citations resolve in docs/papers.md.
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "sl_passes.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::techniques::spherical_lights {

namespace {

struct Scratch {
  std::vector<float> G;           // per SL: log vector of its (rule-adjusted) sphere, n^2
  std::vector<float> key;         // per SL: distance from p to its adjusted sphere
  std::vector<int> active, order, position;
  std::vector<float> f, g;        // 2 log vectors per active SL and their exponentials
  std::vector<float> prefix;
};

// Fills vbar / lbar for every SL at receiver (p, n). Returns nothing for an SL the rules eliminate
// (vbar 0): it neither blocks nor lights p.
void receiver_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const glm::vec3& p,
                    const glm::vec3& n, Scratch& sc, std::vector<float>& vbar, std::vector<glm::vec3>& lbar,
                    IndirectStats& st) {
  const int order = s.order, n2 = order * order;
  const std::size_t m = pose.size();
  sc.G.resize(m * n2);
  sc.key.resize(m);
  sc.position.assign(m, -1);
  sc.active.clear();
  vbar.assign(m, 0.0f);
  lbar.assign(m, glm::vec3(0.0f));

  std::array<float, sh::kMaxCoeffs> y{}, hn{};
  sh::eval_basis(order, sh::Vec3<float>{n.x, n.y, n.z}, hn.data());
  const std::vector<double> cc = sh::clamped_cosine_zh(order);
  std::array<float, kMaxAccOrder> hcoef{}, wrot{};
  for (int l = 0; l < order; ++l) hcoef[l] = static_cast<float>(sh::zh_rotation_factor(l) * cc[l] / sh::kPi);
  for (int l = 0; l < order; ++l)
    for (int mm = -l; mm <= l; ++mm) hn[sh::index(l, mm)] *= hcoef[l];

  for (std::size_t k = 0; k < m; ++k) {
    const glm::vec3 c = pose.centre[k];
    const float r = pose.radius[k];
    // Section 6.2, receiver points inside SLs: the rules of paper 004 section 6.2, shared with SHEXP.
    const AdjustedSphere adj = apply_replacement_rule(s.rule, p, n, c, r);
    const float dist = glm::length(adj.center - p);
    if (!(adj.radius > 0.0f) || !(dist > adj.radius)) {
      ++st.eliminated;
      continue;
    }
    sphere_zh_vector(t.log, p, adj.center, adj.radius, nullptr, sc.G.data() + k * n2);
    sc.key[k] = dist - adj.radius;
    // Average radiance (eqs. 16-18) over the SL itself, whose intensity is defined on its own
    // sphere: theta and the direction of p from its centre, rotated into the SL's rest frame (section
    // 7.1: w_theta rotated by the inverse rotation). A receiver inside the SL sees it at theta = pi/2.
    const glm::vec3 d = p - c;
    const float D = glm::length(d);
    const float theta = D > r ? std::asin(std::min(1.0f, r / D)) : static_cast<float>(sh::kPi / 2);
    const glm::vec3 dl = D > 0.0f ? glm::transpose(pose.rotation[k]) * (d / D) : glm::vec3(0.0f, 0.0f, 1.0f);
    t.weight.lookup(theta, wrot.data());
    sh::eval_basis(order, sh::Vec3<float>{dl.x, dl.y, dl.z}, y.data());
    const float* L = lc.v.data() + k * 3 * n2;
    glm::vec3 acc(0.0f);
    for (int l = 0; l < order; ++l) {
      const float wl = wrot[l] * static_cast<float>(sh::zh_rotation_factor(l));
      for (int mm = -l; mm <= l; ++mm) {
        const int i = sh::index(l, mm);
        acc += wl * y[i] * glm::vec3(L[i], L[n2 + i], L[2 * n2 + i]);
      }
    }
    lbar[k] = acc;
    sc.active.push_back(static_cast<int>(k));
  }
  if (sc.active.empty()) return;

  // Section 7.2: per-sphere blocking orders every SL by its distance from p; per-object blocking
  // orders objects by the distance of their centres (the paper's object-centre sorting) and the SLs
  // of an object by distance. Either way an SL is darkened by every SL before it except the
  // intersecting ones of its own object, so the two differ only in the order (prefix sums below).
  sc.order = sc.active;
  if (s.blocking == Blocking::PerSphere) {
    std::stable_sort(sc.order.begin(), sc.order.end(), [&](int a, int b) { return sc.key[a] < sc.key[b]; });
  } else {
    std::vector<float> od(pose.object_centre.size());
    for (std::size_t o = 0; o < od.size(); ++o) od[o] = glm::length(pose.object_centre[o] - p);
    std::stable_sort(sc.order.begin(), sc.order.end(), [&](int a, int b) {
      const float da = od[pose.object[a]], db = od[pose.object[b]];
      if (da != db) return da < db;
      if (pose.object[a] != pose.object[b]) return pose.object[a] < pose.object[b];
      return sc.key[a] < sc.key[b];
    });
  }
  const std::size_t na = sc.order.size();
  for (std::size_t a = 0; a < na; ++a) sc.position[sc.order[a]] = static_cast<int>(a);
  sc.f.resize(2 * na * n2);
  sc.g.resize(2 * na * n2);
  sc.prefix.assign(n2, 0.0f);
  for (std::size_t a = 0; a < na; ++a) {
    const int i = sc.order[a];
    float* S = sc.f.data() + 2 * a * n2;
    float* SG = S + n2;
    for (int q = 0; q < n2; ++q) S[q] = sc.prefix[q];
    // Eq. 21: intersecting SLs of S_i's own object are not its blockers (their occlusion is in its
    // emission, section 4.2 rule 2).
    for (int j : pose.intersecting[i])
      if (sc.position[j] >= 0 && sc.position[j] < static_cast<int>(a))
        for (int q = 0; q < n2; ++q) S[q] -= sc.G[j * n2 + q];
    const float* Gi = sc.G.data() + i * n2;
    for (int q = 0; q < n2; ++q) {
      SG[q] = S[q] + Gi[q];
      sc.prefix[q] += Gi[q];
    }
  }
  BatchExp be;
  be.order = order;
  be.method = s.exp;
  be.tables = t.sh.get();
  be.plan = &ProductPlan::get(order);
  sh::ExpStats es;
  exp_batch(s.isa, be, sc.f.data(), sc.g.data(), 2 * na, 0, es);
  st.exps += static_cast<long long>(2 * na);
  // Eq. 23: V = exp(S) - exp(S + G_i), the part of S_i's cap no closer SL covers; eq. 24: dotted
  // with the BRDF vector.
  for (std::size_t a = 0; a < na; ++a) {
    const int i = sc.order[a];
    const float* e0 = sc.g.data() + 2 * a * n2;
    const float* e1 = e0 + n2;
    float v = 0.0f;
    for (int q = 0; q < n2; ++q) v += (e0[q] - e1[q]) * hn[q];
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

void accumulate_indirect(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const ReceiverSoA& rec,
                         std::size_t begin, std::size_t end, glm::vec3* out, IndirectStats& stats) {
  Scratch sc;
  std::vector<float> vbar;
  std::vector<glm::vec3> lbar;
  for (std::size_t r = begin; r < end; ++r) {
    const glm::vec3 p(rec.px[r], rec.py[r], rec.pz[r]), n(rec.nx[r], rec.ny[r], rec.nz[r]);
    glm::vec3 e(0.0f);
    if (glm::dot(n, n) > 0.0f) {
      receiver_terms(s, t, pose, lc, p, n, sc, vbar, lbar, stats);
      for (std::size_t i = 0; i < vbar.size(); ++i) e += lbar[i] * vbar[i];
    }
    out[r - begin] = glm::max(e, glm::vec3(0.0f));
  }
}

void indirect_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const glm::vec3& p,
                    const glm::vec3& n, std::vector<float>& vbar, std::vector<glm::vec3>& lbar) {
  Scratch sc;
  IndirectStats st;
  receiver_terms(s, t, pose, lc, p, n, sc, vbar, lbar, st);
}

}  // namespace softgi::techniques::spherical_lights
