// The one render interface all techniques implement, and the registry the CLI, the viewer and the
// benchmark sweeps read.
#pragma once

#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "softgi/render/experiment_def.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/pass_graph.hpp"

namespace softgi::render {

class Technique {
 public:
  virtual ~Technique() = default;
  virtual std::string name() const = 0;
  virtual std::string description() const = 0;
  virtual std::vector<ParamDesc> params() const = 0;
  // The pass graph for this scene and settings. `empty` receives the resources that are empty for
  // this scene (no moving object, no re-radiating proxy, ...), so compile() leaves out their passes.
  virtual PassGraph plan(const scene::Scene& scene, const ParamSet& params, std::set<std::string>& empty) = 0;
  // The paper figures this technique reproduces, for `softgi experiment` (none by default). Their
  // variants may name other registered techniques (a comparison figure).
  virtual std::vector<ExperimentDef> experiments() const { return {}; }
};

using TechniqueFactory = std::function<std::unique_ptr<Technique>()>;
// Throws std::logic_error when the name is taken.
void register_technique(const std::string& name, TechniqueFactory factory);
std::vector<std::string> technique_names();
// Throws std::invalid_argument naming the unknown technique and the known ones.
std::unique_ptr<Technique> create_technique(const std::string& name);
// A ParamSet with the technique's descriptions and defaults.
ParamSet default_params(const Technique& t);

// softgi::techniques::register_all() (techniques/registry.hpp) registers every technique softgi
// ships; registration is explicit because static registrars in a static library are dropped by the
// linker.

}  // namespace softgi::render
