// Receiver clusters of per-vertex receivers (paper 004 section 6.3).
#include "receivers.hpp"

#include <algorithm>
#include <atomic>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "softgi/render/frame.hpp"

namespace softgi::techniques::common {

namespace {

constexpr int kLloydIterations = 30;
constexpr int kLloydIterationsMoving = 3;  // warm-started per frame when geometry moves

std::string receivers_signature(const scene::Scene& scene, const scene::PosedScene& posed, int clusters) {
  std::ostringstream os;
  os << &scene << '|' << scene.source << '|' << scene.name << '|' << clusters;
  for (const auto& o : posed.objects) os << '|' << o.node << ':' << o.positions.size();
  return os.str();
}

}  // namespace

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

std::shared_ptr<const VertexReceivers> ReceiverClustering::update(const std::string& technique, render::FrameContext& ctx, int clusters) {
  const scene::PosedScene& posed = ctx.posed;
  std::size_t total = 0;
  for (const auto& o : posed.objects) total += o.positions.size();
  if (total == 0) throw std::invalid_argument(technique + ": scene '" + ctx.scene.name + "' has no vertices to shade");
  if (total > (std::size_t{1} << 31)) throw std::invalid_argument(technique + ": scene '" + ctx.scene.name + "' has too many vertices");
  for (const auto& o : posed.objects)
    if (o.normals.size() != o.positions.size())
      throw std::invalid_argument(technique + ": object " + std::to_string(o.node) + " in scene '" + ctx.scene.name + "' has " +
                                  std::to_string(o.normals.size()) + " normals for " + std::to_string(o.positions.size()) + " vertices");
  const int want = clusters > 0 ? clusters : std::max<int>(1, static_cast<int>((total + ReceiverClustering::kAutoReceiversPerCluster / 2) / ReceiverClustering::kAutoReceiversPerCluster));
  const std::string key = receivers_signature(ctx.scene, posed, want);
  
  std::lock_guard<std::mutex> lock(m_);
  int iterations = 0, objects_reclustered = 0;
  const bool recluster = key_ != key;
  if (recluster) last_positions_.assign(posed.objects.size(), {});
  // Lloyd clustering per object (a cluster never spans two objects), the count split by vertex
  // count. An object whose vertices did not move keeps its clusters; one that moved is re-clustered
  // warm-started from its last centres (section 6.3: recompute when geometry moves).
  std::vector<glm::vec3> centres;
  std::vector<int> cobj;
  std::vector<std::vector<int>> assign(posed.objects.size());
  for (std::size_t o = 0; o < posed.objects.size(); ++o) {
    const auto& pts = posed.objects[o].positions;
    if (pts.empty()) continue;
    std::vector<glm::vec3> old;
    for (std::size_t c = 0; c < centres_.size(); ++c)
      if (!recluster && cluster_object_[c] == static_cast<int>(o)) old.push_back(centres_[c]);
    const int base = static_cast<int>(centres.size());
    assign[o].resize(pts.size());
    if (!recluster && last_positions_[o] == pts) {
      const int old_base = assignment_[o].empty() ? 0 : *std::min_element(assignment_[o].begin(), assignment_[o].end());
      for (std::size_t v = 0; v < pts.size(); ++v) assign[o][v] = base + assignment_[o][v] - old_base;
      for (const auto& c : old) {
        centres.push_back(c);
        cobj.push_back(static_cast<int>(o));
      }
      continue;
    }
    const int k = std::max(1, static_cast<int>(std::lround(static_cast<double>(want) * pts.size() / total)));
    const bool warm = !recluster && static_cast<int>(old.size()) == k;
    LloydResult lr = lloyd_cluster(pts, k, warm ? kLloydIterationsMoving : kLloydIterations, 7u + static_cast<unsigned>(o),
                                   warm ? &old : nullptr);
    iterations += lr.iterations;
    ++objects_reclustered;
    for (std::size_t v = 0; v < pts.size(); ++v) assign[o][v] = base + lr.assignment[v];
    for (const auto& c : lr.centres) {
      centres.push_back(c);
      cobj.push_back(static_cast<int>(o));
    }
    last_positions_[o] = pts;
  }
  assignment_ = std::move(assign);
  centres_ = std::move(centres);
  cluster_object_ = std::move(cobj);
  key_ = key;

  // Receivers in cluster order; cluster bounds (p_R, r_R) and the central point p* from this pose.
  auto r = std::make_shared<VertexReceivers>();
  const int nc = static_cast<int>(centres_.size());
  std::vector<std::size_t> count(nc + 1, 0);
  for (const auto& a : assignment_)
    for (int c : a) ++count[c + 1];
  for (int c = 0; c < nc; ++c) count[c + 1] += count[c];
  r->soa.resize(total);
  r->object.resize(total);
  r->vertex.resize(total);
  r->index.resize(posed.objects.size());
  std::vector<std::size_t> fill(count.begin(), count.end() - 1);
  for (std::size_t o = 0; o < posed.objects.size(); ++o) {
    const auto& obj = posed.objects[o];
    r->index[o].resize(obj.positions.size());
    for (std::size_t v = 0; v < obj.positions.size(); ++v) {
      const std::size_t i = fill[assignment_[o][v]]++;
      r->soa.set(i, obj.positions[v], obj.normals[v]);
      r->object[i] = static_cast<int>(o);
      r->vertex[i] = static_cast<int>(v);
      r->index[o][v] = static_cast<std::uint32_t>(i);
    }
  }
  r->clusters.resize(nc);
  tbb::parallel_for(0, nc, [&](int c) {
    ReceiverCluster& rc = r->clusters[c];
    rc.begin = count[c];
    rc.end = count[c + 1];
    glm::dvec3 sum(0.0);
    for (std::size_t i = rc.begin; i < rc.end; ++i) sum += glm::dvec3(r->soa.px[i], r->soa.py[i], r->soa.pz[i]);
    rc.centre = glm::vec3(sum / static_cast<double>(std::max<std::size_t>(1, rc.end - rc.begin)));
    float rad = 0.0f, best = std::numeric_limits<float>::max();
    for (std::size_t i = rc.begin; i < rc.end; ++i) {
      const float d = glm::length(glm::vec3(r->soa.px[i], r->soa.py[i], r->soa.pz[i]) - rc.centre);
      rad = std::max(rad, d);
      if (d < best) {
        best = d;
        rc.star = glm::vec3(r->soa.px[i], r->soa.py[i], r->soa.pz[i]);
      }
    }
    rc.radius = rad;
  });
  std::size_t maxc = 0;
  for (const auto& c : r->clusters) maxc = std::max(maxc, c.end - c.begin);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(total);
  rec.counters["clusters"] = nc;
  rec.counters["receivers_per_cluster_mean"] = static_cast<double>(total) / std::max(1, nc);
  rec.counters["receivers_per_cluster_max"] = static_cast<double>(maxc);
  rec.counters["lloyd_iterations"] = iterations;
  rec.counters["reclustered"] = recluster;
  rec.counters["objects_reclustered"] = objects_reclustered;
  rec.bytes = r->bytes();
  return r;
}


}  // namespace softgi::techniques::common
