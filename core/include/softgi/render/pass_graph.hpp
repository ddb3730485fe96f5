// Pass graphs: each pass declares the resources it reads and writes; a graph is compiled backwards
// from the requested outputs, and passes whose outputs nothing needs, or whose required inputs are
// empty for the scene, are left out (docs/architecture.md).
#pragma once

#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace softgi::render {

class FrameContext;
using PassFn = std::function<void(FrameContext&)>;

struct PassDesc {
  std::string name;
  std::vector<std::string> reads;           // required: the pass is left out when one is empty
  std::vector<std::string> optional_reads;  // used when present (an empty one reads as zero)
  std::vector<std::string> writes;
  std::string help;
  // Implementations keyed by backend name (render::backend_names()), plus kHostImpl: host code that
  // runs on any backend without an implementation of its own (the CPU backend runs nothing else).
  // The null backend runs none.
  std::map<std::string, PassFn> impl;
};

// The key of PassDesc::impl for host code: the CPU reference implementation of a pass, run by every
// backend that has no implementation of its own for it.
inline constexpr const char* kHostImpl = "host";
// PassDesc::impl with only the host implementation.
std::map<std::string, PassFn> host_impl(PassFn fn);

struct PrunedPass {
  std::string name, reason;
};

struct CompiledGraph {
  std::vector<int> order;               // indices into PassGraph::passes(), dependency order
  std::vector<PrunedPass> pruned;       // every pass not in `order`, with why
  std::set<std::string> empty;          // resources known empty (given, or written only by pruned passes)
  std::set<std::string> live;           // resources that will be produced
  // PassGraph::warn_if_empty messages of the resources that are empty (FrameResult::warnings).
  std::vector<std::string> warnings;
};

class PassGraph {
 public:
  // Resources that exist before any pass runs (e.g. "scene", "camera"). Reading anything else
  // requires a writer in the graph.
  void add_input(const std::string& resource) { inputs_.insert(resource); }
  int add(PassDesc pass);
  const std::vector<PassDesc>& passes() const { return passes_; }
  const std::set<std::string>& inputs() const { return inputs_; }
  // Leaving out what a scene does not need is silent; leaving out what the user asked a technique
  // for (shadows of a scene without proxy spheres) is not: when `resource` turns out empty, the
  // compiled graph carries `message` as a frame warning.
  void warn_if_empty(const std::string& resource, std::string message) { empty_warnings_[resource] = std::move(message); }

  // Builds the schedule for `outputs`. `empty` lists resources that are empty for this scene
  // (e.g. "moving_objects" for a static scene, "reradiating_proxies" when no proxy re-radiates).
  // Throws std::invalid_argument for an unknown output, a read with no writer, two writers of one
  // resource, or a cycle, naming the pass and resource.
  CompiledGraph compile(const std::vector<std::string>& outputs, const std::set<std::string>& empty = {}) const;

 private:
  std::vector<PassDesc> passes_;
  std::set<std::string> inputs_;
  std::map<std::string, std::string> empty_warnings_;
};

}  // namespace softgi::render
