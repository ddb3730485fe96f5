// Backends execute compiled pass graphs.
#pragma once

#include <string>
#include <vector>

#include "softgi/render/technique.hpp"

namespace softgi::render {

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // Poses the scene at request.time, plans, compiles for request.outputs, executes and times every
  // pass. A needed pass without an implementation for this backend is an error naming both.
  virtual FrameResult render(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                             const RenderRequest& request);

 protected:
  virtual void execute_pass(const PassDesc& pass, FrameContext& ctx);
};

// Runs no pass implementation; records which passes would run (for graph tests).
class NullBackend : public Backend {
 public:
  std::string name() const override { return "null"; }
  std::vector<std::string> executed;

 protected:
  void execute_pass(const PassDesc& pass, FrameContext& ctx) override;
};

}  // namespace softgi::render
