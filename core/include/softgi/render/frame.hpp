// What a frame produces, and the context passes run in.
#pragma once

#include <any>
#include <cstddef>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/pass_graph.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::render {

struct PassRecord {
  std::string name;
  double wall_seconds = 0.0;
  double gpu_seconds = -1.0;                 // GPU timestamps where the backend has them
  std::map<std::string, double> counters;    // receivers, blockers accumulated, ...
  std::size_t bytes = 0;                     // tables and buffers this pass allocated or holds
};

struct FrameResult {
  std::string technique, backend;
  Image direct, indirect, final_image;  // display resolution, outgoing radiance (linear HDR)
  // Per-vertex outgoing radiance per posed object, where a technique shades vertices.
  std::vector<std::vector<glm::vec3>> vertex_radiance;
  std::vector<PassRecord> passes;       // executed passes, in order
  std::vector<PrunedPass> pruned;       // left-out passes and why
  double total_seconds = 0.0;
  std::size_t peak_rss_bytes = 0;       // process peak resident memory after the frame
  std::size_t bytes() const;            // sum over passes
};

struct RenderRequest {
  double time = 0.0;
  int width = 0, height = 0;  // 0: the scene camera's
  std::vector<std::string> outputs = {"final"};
};

// Typed blackboard of a frame's resources plus what passes report.
class FrameContext {
 public:
  FrameContext(const scene::Scene& scene, const scene::PosedScene& posed, const ParamSet& params, int width,
               int height, FrameResult& result)
      : scene(scene), posed(posed), params(params), width(width), height(height), result(result) {}

  const scene::Scene& scene;
  const scene::PosedScene& posed;
  const ParamSet& params;
  const int width, height;
  FrameResult& result;

  template <class T>
  T& put(const std::string& name, T value) {
    resources_[name] = std::move(value);
    return std::any_cast<T&>(resources_[name]);
  }
  template <class T>
  T& get(const std::string& name) {
    auto it = resources_.find(name);
    if (it == resources_.end()) throw std::logic_error("frame resource '" + name + "' was never produced");
    T* p = std::any_cast<T>(&it->second);
    if (!p) throw std::logic_error("frame resource '" + name + "' has another type");
    return *p;
  }
  bool has(const std::string& name) const { return resources_.count(name) != 0; }
  // The record of the pass being executed (counters, bytes).
  PassRecord& record() { return result.passes.back(); }

 private:
  std::map<std::string, std::any> resources_;
};

// Peak resident set size of this process (VmHWM), 0 where unavailable.
std::size_t peak_rss_bytes();

}  // namespace softgi::render
