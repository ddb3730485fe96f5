// Backends execute compiled pass graphs; the backend registry lists those a build has. The render
// calls here are the library API: every command, benchmark and test renders through them.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"

namespace softgi::render {

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // The device passes run on (FrameContext::device); null for the host-only CPU backend.
  virtual Device* device() { return nullptr; }
  // For run records: what the device is (name, type, driver, ...); empty for the CPU backend.
  virtual std::map<std::string, std::string> device_record() const { return {}; }
  // Poses the scene at request.time, plans, compiles for request.outputs, executes and times every
  // pass, and records each pass's host <-> device transfers. A needed pass without an implementation
  // for this backend is an error naming both.
  virtual FrameResult render(Technique& technique, const scene::Scene& scene, const ParamSet& params,
                             const RenderRequest& request);

 protected:
  virtual void execute_pass(const PassDesc& pass, FrameContext& ctx);
  // Host <-> device bytes moved since the backend was created (zero without a device).
  virtual TransferBytes transfer_total() const { return {}; }
};

// Runs no pass implementation; records which passes would run (for graph tests).
class NullBackend : public Backend {
 public:
  std::string name() const override { return "null"; }
  std::vector<std::string> executed;

 protected:
  void execute_pass(const PassDesc& pass, FrameContext& ctx) override;
};

// What `backend` runs for `pass`: its own implementation, else its implementation of a shared pass,
// else the host implementation (kHostImpl names the host one alone); null when there is none.
const PassFn* find_pass_impl(const PassDesc& pass, const std::string& backend);

// A frame run pass by pass by the caller: posed, planned and compiled as Backend::render does, so
// that a test can run one pass on two backends from the same inputs (backend parity) or stop after
// a pass. run() records each pass in result() as Backend::render would. The scene and the
// parameters must outlive the frame.
class SteppedFrame {
 public:
  SteppedFrame(Technique& technique, const scene::Scene& scene, const ParamSet& params, const RenderRequest& request,
               Device* device = nullptr);
  SteppedFrame(const SteppedFrame&) = delete;
  SteppedFrame& operator=(const SteppedFrame&) = delete;
  // The passes to run, in dependency order.
  const std::vector<const PassDesc*>& passes() const { return order_; }
  const PassDesc& pass(const std::string& name) const;  // throws std::invalid_argument naming it
  FrameContext& context() { return *ctx_; }
  FrameResult& result() { return result_; }
  // Runs `pass` as `backend` would (find_pass_impl), recorded as `label` (default: the pass name).
  // Throws std::logic_error when the backend has no implementation of it.
  void run(const PassDesc& pass, const std::string& backend, const std::string& label = "");

 private:
  FrameResult result_;
  scene::PosedScene posed_;
  PassGraph graph_;
  std::vector<const PassDesc*> order_;
  std::unique_ptr<FrameContext> ctx_;
};

// --- The backend registry ---------------------------------------------------------------------

struct BackendOptions {
  std::string device;   // a device by name or index, for backends that select one ("" = the best)
  int validation = -1;  // API validation layers: 1 on, 0 off, -1 the backend's default
};

struct BackendInfo {
  std::string name, description;
  bool selects_device = false;  // BackendOptions::device means something
  // "" when the backend can run on this machine, else why it cannot (no driver, no device, ...).
  std::function<std::string()> unavailable;
  std::function<std::unique_ptr<Backend>(const BackendOptions&)> create;
};

// Throws std::logic_error when the name is taken. The first registered backend is the reference
// the others are compared with.
void register_backend(BackendInfo info);
std::vector<std::string> backend_names();  // registration order
// Throws std::invalid_argument naming the unknown backend and the registered ones.
const BackendInfo& backend_info(const std::string& name);
// The reference backend's name (the first registered); throws std::logic_error when none is.
std::string reference_backend_name();
// Throws std::invalid_argument for an unknown backend, for a device option the backend does not
// take, and for an unavailable backend (with the reason).
std::unique_ptr<Backend> create_backend(const std::string& name, const BackendOptions& options = {});

// --- Rendering ----------------------------------------------------------------------------------

// One frame of the registered technique `technique` with `params` (defaults where null), on a
// technique object made for it: no state carries over from an earlier call (a caller rendering a
// sequence keeps one Technique and calls Backend::render, so that tables and hierarchies are built
// once).
FrameResult render_frame(Backend& backend, const std::string& technique, const scene::Scene& scene,
                         const ParamSet* params, const RenderRequest& request);

// The display G-buffer alone (the shared "gbuffer" pass), as a frame of its own: what compare and
// experiments measure errors over.
struct GBufferFrame {
  GBuffer gbuffer;
  FrameResult frame;
};
GBufferFrame render_gbuffer(Backend& backend, const scene::Scene& scene, const RenderRequest& request);

}  // namespace softgi::render
