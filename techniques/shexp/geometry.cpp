// SHEXP geometry: receiver clusters and hierarchy cuts with ratio vectors (paper 004 section 6.3,
// eqs. 36-37), the product-space baseline (eq. 6) and the projected reference.
#include <xmmintrin.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "shexp_internal.hpp"
#include "softgi/sh/product.hpp"


namespace softgi::techniques::shexp {
// ---------------------------------------------------------------------------------------------

LloydResult lloyd_cluster(const std::vector<glm::vec3>& points, int k, int max_iterations, unsigned seed,
                          const std::vector<glm::vec3>* initial_centres) {
  const std::size_t n = points.size();
  if (k < 1) throw std::invalid_argument("lloyd_cluster: cluster count " + std::to_string(k) + " < 1");
  LloydResult res;
  if (n == 0) return res;
  k = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(k), n));
  std::mt19937 rng(seed);
  auto& c = res.centres;
  if (initial_centres && static_cast<int>(initial_centres->size()) == k) {
    c = *initial_centres;
  } else {
    // k-means++ seeding: each next centre drawn with probability proportional to the squared
    // distance to the nearest centre so far.
    std::vector<double> d2(n, std::numeric_limits<double>::max());
    c.push_back(points[std::uniform_int_distribution<std::size_t>(0, n - 1)(rng)]);
    while (static_cast<int>(c.size()) < k) {
      double total = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        glm::vec3 e = points[i] - c.back();
        d2[i] = std::min(d2[i], static_cast<double>(glm::dot(e, e)));
        total += d2[i];
      }
      if (!(total > 0.0)) break;  // fewer distinct points than clusters
      double u = std::uniform_real_distribution<double>(0.0, total)(rng), acc = 0.0;
      std::size_t pick = n - 1;
      for (std::size_t i = 0; i < n; ++i) {
        acc += d2[i];
        if (acc >= u) {
          pick = i;
          break;
        }
      }
      c.push_back(points[pick]);
    }
    k = static_cast<int>(c.size());
  }
  res.assignment.assign(n, -1);
  std::vector<float> dist(n, 0.0f);
  // Assigns every point to its nearest centre; returns how many assignments changed.
  auto assign = [&]() {
    std::atomic<long long> changed{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
      long long ch = 0;
      for (std::size_t i = r.begin(); i != r.end(); ++i) {
        int best = 0;
        float bd = std::numeric_limits<float>::max();
        for (int j = 0; j < k; ++j) {
          glm::vec3 e = points[i] - c[j];
          float d = glm::dot(e, e);
          if (d < bd) {
            bd = d;
            best = j;
          }
        }
        dist[i] = bd;
        if (res.assignment[i] != best) {
          res.assignment[i] = best;
          ++ch;
        }
      }
      changed += ch;
    });
    return changed.load();
  };
  for (int it = 0; it < std::max(1, max_iterations); ++it) {
    res.iterations = it + 1;
    const long long changed = assign();
    std::vector<glm::dvec3> sum(k, glm::dvec3(0.0));
    std::vector<std::size_t> cnt(k, 0);
    for (std::size_t i = 0; i < n; ++i) {
      sum[res.assignment[i]] += glm::dvec3(points[i]);
      ++cnt[res.assignment[i]];
    }
    bool reseeded = false;
    for (int j = 0; j < k; ++j) {
      if (cnt[j]) {
        c[j] = glm::vec3(sum[j] / static_cast<double>(cnt[j]));
      } else {
        // An empty cluster restarts at the point farthest from its centre.
        std::size_t far = static_cast<std::size_t>(std::max_element(dist.begin(), dist.end()) - dist.begin());
        c[j] = points[far];
        dist[far] = 0.0f;
        reseeded = true;
      }
    }
    if (changed == 0 && !reseeded) break;
  }
  // Final assignment to the final centres, then empty clusters dropped.
  assign();
  std::vector<int> remap(k, -1);
  std::vector<glm::vec3> kept;
  for (std::size_t i = 0; i < n; ++i) {
    int a = res.assignment[i];
    if (remap[a] < 0) {
      remap[a] = static_cast<int>(kept.size());
      kept.push_back(c[a]);
    }
  }
  for (auto& a : res.assignment) a = remap[a];
  res.centres = std::move(kept);
  return res;
}

// ---------------------------------------------------------------------------------------------

BlockerList flat_list(const std::vector<std::vector<scene::Sphere>>& sets, int order) {
  BlockerList b;
  b.order = order;
  for (const auto& set : sets)
    for (const auto& s : set)
      if (s.radius > 0.0f) b.push(s.center, s.radius, nullptr);
  return b;
}

namespace {
float angular_radius(const glm::vec3& p, const scene::Sphere& s) {
  const float dist = glm::length(s.center - p);
  return dist > s.radius ? std::asin(s.radius / dist) : static_cast<float>(sh::kPi / 2);
}
}  // namespace

BlockerList make_cut(const std::vector<const proxies::SphereHierarchy*>& trees,
                     const std::vector<std::vector<scene::Sphere>>& leaves, const ZhTable& log_table, const glm::vec3& pR,
                     float rR, const glm::vec3& pstar, const CutOptions& opt, CutStats* stats) {
  const int n = log_table.order;
  const int n2 = n * n;
  BlockerList out;
  out.order = n;
  const double sin_max = std::sin(opt.theta_max);
  CutStats st;
  std::array<float, sh::kMaxCoeffs> fb{}, fd{}, tmp{};
  std::vector<int> stack, detail;
  for (std::size_t t = 0; t < trees.size(); ++t) {
    const proxies::SphereHierarchy* tree = trees[t];
    if (!tree || tree->root() < 0) continue;
    const auto& nodes = tree->nodes();
    // A leaf's own sphere where the caller passes the leaf list, else its bound (the same sphere).
    auto sphere_of = [&](const proxies::SphereNode& nd) -> const scene::Sphere& {
      if (nd.children.empty() && nd.leaf >= 0 && t < leaves.size() && nd.leaf < static_cast<int>(leaves[t].size()))
        return leaves[t][nd.leaf];
      return nd.bound;
    };
    stack.assign(1, tree->root());
    while (!stack.empty()) {
      const int id = stack.back();
      stack.pop_back();
      ++st.nodes_visited;
      const proxies::SphereNode& node = nodes[id];
      const bool leaf = node.children.empty();
      const scene::Sphere& s = sphere_of(node);
      // eq. 36: the node subtends less than theta_max over the whole receiver cluster.
      const bool small = s.radius < sin_max * (glm::length(s.center - pR) - rR);
      if (!leaf && !small) {
        for (int ch : node.children) stack.push_back(ch);
        continue;
      }
      if (leaf || !opt.ratio_vectors) {
        if (leaf) ++st.leaves; else ++st.inner;
        out.push(s.center, s.radius, nullptr);
        continue;
      }
      ++st.inner;
      // Ratio vector (eq. 37) from the bounding (f_b) and detailed (f_d) log vectors at p*.
      sphere_zh_vector(log_table, pstar, s.center, s.radius, nullptr, fb.data());
      std::fill(fd.begin(), fd.begin() + n2, 0.0f);
      detail.assign(1, id);
      while (!detail.empty()) {
        const int d = detail.back();
        detail.pop_back();
        const proxies::SphereNode& dn = nodes[d];
        if (!dn.children.empty() && !(opt.theta_min > 0.0 && angular_radius(pstar, dn.bound) < opt.theta_min)) {
          for (int ch : dn.children) detail.push_back(ch);
          continue;
        }
        ++st.detail_spheres;
        const scene::Sphere& ds = sphere_of(dn);
        sphere_zh_vector(log_table, pstar, ds.center, ds.radius, nullptr, tmp.data());
        for (int i = 0; i < n2; ++i) fd[i] += tmp[i];
      }
      std::array<float, kMaxAccOrder> w{};
      for (int l = 0; l < n; ++l) {
        double num = 0.0, den = 0.0;
        for (int m = -l; m <= l; ++m) {
          const int i = sh::index(l, m);
          num += static_cast<double>(fb[i]) * fd[i];
          den += static_cast<double>(fb[i]) * fb[i];
        }
        // A band the bounding vector does not excite carries no information: keep it unscaled.
        w[l] = den > 1e-20 ? static_cast<float>(num / den) : 1.0f;
      }
      out.push(s.center, s.radius, w.data());
    }
  }
  if (stats) {
    stats->nodes_visited += st.nodes_visited;
    stats->leaves += st.leaves;
    stats->inner += st.inner;
    stats->detail_spheres += st.detail_spheres;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

long long accumulate_product(const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                             std::size_t end, const BlockerList& blockers, float* out) {
  const int n = vis_table.order;
  const int n2 = n * n;
  const sh::TripleProduct& tp = sh::TripleProduct::get(n);
  // The same flush-to-zero as the log-space kernels (kernel.cpp), so that neither side of the
  // product-vs-log comparison pays for subnormal arithmetic.
  const unsigned csr = _mm_getcsr();
  _mm_setcsr(csr | 0x8040u);
  struct Restore {
    unsigned v;
    ~Restore() { _mm_setcsr(v); }
  } restore{csr};
  long long products = 0;
  std::array<float, sh::kMaxCoeffs> acc{}, g{}, tmp{};
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nn(rec.nx[i], rec.ny[i], rec.nz[i]);
    std::fill(acc.begin(), acc.begin() + n2, 0.0f);
    acc[0] = static_cast<float>(sh::kSqrt4Pi);  // the constant 1
    for (std::size_t b = 0; b < blockers.size(); ++b) {
      const AdjustedSphere s = apply_replacement_rule(rule, p, nn, glm::vec3(blockers.cx[b], blockers.cy[b], blockers.cz[b]),
                                                      blockers.r[b]);
      if (!(s.radius > 0.0f)) continue;  // eliminated: visibility 1 changes nothing
      sphere_zh_vector(vis_table, p, s.center, s.radius, nullptr, g.data());
      tp.product(acc.data(), g.data(), tmp.data());
      std::copy(tmp.begin(), tmp.begin() + n2, acc.begin());
      ++products;
    }
    std::copy(acc.begin(), acc.begin() + n2, out + i * n2);
  }
  return products;
}

void project_visibility(int order, int bands, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                        std::size_t end, const BlockerList& blockers, float* out) {
  const int n2 = order * order;
  static thread_local std::map<int, std::pair<sh::SphereQuadrature, std::vector<float>>> cache;
  auto& entry = cache[bands * 16 + order];
  if (entry.first.dirs.empty()) {
    entry.first = sh::make_sphere_quadrature(bands);
    entry.second.resize(entry.first.dirs.size() * n2);
    for (std::size_t k = 0; k < entry.first.dirs.size(); ++k) {
      std::array<double, sh::kMaxCoeffs> y{};
      sh::eval_basis(order, entry.first.dirs[k], y.data());
      for (int i = 0; i < n2; ++i) entry.second[k * n2 + i] = static_cast<float>(y[i] * entry.first.weights[k]);
    }
  }
  const sh::SphereQuadrature& q = entry.first;
  std::vector<AdjustedSphere> adj;
  for (std::size_t i = begin; i < end; ++i) {
    const glm::vec3 p(rec.px[i], rec.py[i], rec.pz[i]), nn(rec.nx[i], rec.ny[i], rec.nz[i]);
    adj.clear();
    for (std::size_t b = 0; b < blockers.size(); ++b) {
      AdjustedSphere s = apply_replacement_rule(rule, p, nn, glm::vec3(blockers.cx[b], blockers.cy[b], blockers.cz[b]), blockers.r[b]);
      if (s.radius > 0.0f) adj.push_back(s);
    }
    float* g = out + i * n2;
    std::fill(g, g + n2, 0.0f);
    for (std::size_t k = 0; k < q.dirs.size(); ++k) {
      const glm::vec3 d(static_cast<float>(q.dirs[k].x), static_cast<float>(q.dirs[k].y), static_cast<float>(q.dirs[k].z));
      bool blocked = false;
      for (const auto& s : adj) {
        // The ray p + t d (t > 0) meets the sphere: the cone of directions within its angular radius.
        const glm::vec3 c = s.center - p;
        const float dist2 = glm::dot(c, c), r2 = s.radius * s.radius;
        const float cd = glm::dot(c, d);
        if (dist2 <= r2 || (cd > 0.0f && dist2 - cd * cd <= r2)) {
          blocked = true;
          break;
        }
      }
      if (blocked) continue;
      const float* y = entry.second.data() + k * n2;
      for (int j = 0; j < n2; ++j) g[j] += y[j];
    }
  }
}

}  // namespace softgi::techniques::shexp
