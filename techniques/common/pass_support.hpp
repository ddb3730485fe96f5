// Pieces every technique's passes share: input checks with one message style, the windowed
// environment light, and the cached light-lobe tables of spherical lights. Not installed; include
// by path (techniques/common/...).
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "accumulation.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/pass_graph.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::techniques::common {

double seconds_since(std::chrono::steady_clock::time_point t0);

// Every posed proxy sphere must be finite with radius >= 0 (a bad one turns every receiver's SH
// vector into NaN); with check_albedo, every proxy set's albedo finite and >= 0 too (techniques that
// re-radiate from proxies). std::invalid_argument "<technique>: proxy set '<name>' of scene ...",
// naming the set, the sphere, the time and the values.
void check_proxy_spheres(const std::string& technique, const render::FrameContext& ctx, bool check_albedo);

// The proxy spheres a technique's shadow (and indirect) passes read, as graph input `resource`:
// empty when no proxy set of the scene has a sphere, and then a frame warning saying what
// `technique` leaves out (`effects`, e.g. "shadows") and how to give the scene proxies.
void blocker_spheres_input(const std::string& technique, const std::string& effects, const scene::Scene& scene,
                           const std::string& resource, render::PassGraph& graph, std::set<std::string>& empty);

// Per-vertex receivers show a proxy's shadow only where their vertices are closer together than
// the shadow is wide (about a proxy's radius at contact). Warns (FrameContext::warn) for each posed
// object whose mean edge length exceeds the median radius of the scene's posed proxy spheres,
// naming the object and both lengths; nothing without proxies.
void warn_coarse_receivers(const std::string& technique, render::FrameContext& ctx);

// A key that changes whenever anything the environment's SH projection depends on changes.
std::string environment_signature(const scene::Environment& env);
// The order-n SH of the scene's environment, cosine-windowed (paper 004 section 7) when
// window_h > 0. Throws std::invalid_argument prefixed with `technique` for a non-finite projection.
std::vector<glm::vec3> windowed_environment_sh(const std::string& technique, const scene::Scene& scene, int order,
                                               double window_h);

// A thread-safe memo of immutable values shared across frames: get() returns the value for `key`,
// built by make() outside the lock the first time (two threads may both build it once; the first
// stored wins), and says whether it was cached.
template <class K, class V>
class SharedCache {
 public:
  template <class F>
  std::shared_ptr<const V> get(const K& key, F&& make, bool& cached) {
    {
      std::lock_guard<std::mutex> lock(m_);
      auto it = map_.find(key);
      if (it != map_.end()) {
        cached = true;
        return it->second;
      }
    }
    cached = false;
    std::shared_ptr<const V> v = make();
    std::lock_guard<std::mutex> lock(m_);
    return map_.emplace(key, std::move(v)).first->second;
  }

 private:
  std::mutex m_;
  std::map<K, std::shared_ptr<const V>> map_;
};

// The core's double-precision tables for log-space blocker accumulation (paper 004 section 6.1:
// cap log and cap visibility ZH, OL a/b) at `order`, `resolution` rows in theta, without the
// interpolation-error measurement (a per-frame cost the passes do not need).
std::shared_ptr<const sh::ShTables> accumulation_tables(int order, int resolution, double log_threshold);

// Light-lobe tables of spherical lights (paper 004 section 7, common::make_light_lobe_table), built
// once per (order, window_h) and shared across frames.
class LightTableCache {
 public:
  static constexpr int kRowsTheta = 48;  // theta in [0, 90] degrees
  static constexpr int kRowsF = 96;      // f in [0, 180] degrees
  std::shared_ptr<const common::LightLobeTable> get(int order, double window_h, bool& cached);
  // The body of a "light_tables" pass: the table into `resource`, with counters cached, lights,
  // max_fit_error and bytes.
  void run_pass(int order, double window_h, render::FrameContext& ctx, const std::string& resource);

 private:
  std::mutex m_;
  std::map<std::pair<int, double>, std::shared_ptr<const common::LightLobeTable>> tables_;
};

}  // namespace softgi::techniques::common
