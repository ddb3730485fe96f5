// The one render interface all techniques implement, and the registry the CLI, the viewer and the
// benchmark sweeps read.
#pragma once

#include <cstddef>
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

// --- Frame memory -------------------------------------------------------------------------------
// What a frame allocates, estimated before the first pass so that a frame too large for the backend
// fails at once with an error naming the resource, its size and the limit (Backend::render), not
// with std::bad_alloc or an unnamed driver error after minutes of work. Only the large resources are
// listed: those that grow with the resolution, the receivers or the vertices.
enum class MemoryPlace {
  Host,   // process memory (std::vector and friends)
  Device  // memory a device backend allocates through its API (buffers, images)
};
struct MemoryItem {
  std::string name;  // as errors name it: a frame resource ("gbuffer"), or a device buffer's name
  std::size_t bytes = 0;
  MemoryPlace place = MemoryPlace::Host;
  // The pass that allocates it, or whose result it holds ("" = always counted). Host items count
  // when the pass runs at all; device items only on a backend that runs the pass with an
  // implementation of its own (its kernels), never on the host fallback.
  std::string pass;
  // Freed when `pass` ends (scratch of one pass): the frame needs the persistent items plus the
  // largest pass's transient ones, not the sum of all.
  bool transient = false;
  // Device items: one storage buffer (the device's maxStorageBufferRange applies) rather than an
  // image or a transfer buffer (only maxMemoryAllocationSize applies). Every device item is one
  // allocation.
  bool storage_buffer = false;
  // Host items: made by the pass's host implementation only; a device backend's kernels keep it in
  // device memory (a deferred resource), so it is not counted where they run the pass.
  bool host_only = false;
};

// Sizes of the common image-sized resources, the closed forms technique estimates are made of.
std::size_t pixel_count(int width, int height);
// A render::GBuffer of width x height pixels holding `planes` (GBufferPlanes; by default every
// plane: position, normal, albedo, view_dir, depth, object, primitive, barycentric).
std::size_t gbuffer_bytes(int width, int height, unsigned planes = kGBufferAll);
// The planes of a frame's G-buffer: technique.gbuffer_planes(params), or every plane when `outputs`
// requests the G-buffer itself.
class Technique;
unsigned frame_gbuffer_planes(const Technique& technique, const ParamSet& params, const std::vector<std::string>& outputs);
// A render::Image (linear RGB float).
std::size_t image_bytes(int width, int height);
// ceil(size / scale): the receiver buffer's edge (common_passes.hpp, add_receiver_gbuffer_pass).
int scaled_size(int size, int scale);
// Vertices of every object of the scene (nodes with a mesh): the per-vertex receivers.
std::size_t scene_vertex_count(const scene::Scene& scene);

// What a viewer draws over the image for a technique, beyond the scene's proxy spheres (which any
// viewer poses itself): the technique's own proxies as discs, its spatial structure as boxes.
struct OverlayGeometry {
  struct Point {
    glm::vec3 position{0.0f};
    float radius = 0.0f;
  };
  struct Box {
    glm::vec3 lo{0.0f}, hi{0.0f};
  };
  std::vector<Point> points;
  std::vector<Box> boxes;
  std::string points_label, boxes_label;  // what they are ("point proxies", "occupied voxels")
  // The technique shades with the scene's proxy spheres (scene::ProxySet), so they belong in its
  // overlay too.
  bool scene_spheres = true;
};

// What casts a technique's shadows: what "the same problem, solved exactly" means when its error is
// split by source (softgi report's error budget, docs/reports.md).
enum class ShadowBlockers {
  SceneGeometry,  // the scene's triangles, or proxies of its own sampled from all of them
  SphereProxies,  // the scene's proxy sphere sets alone: an object without them shadows nothing
};

class Technique {
 public:
  virtual ~Technique() = default;
  virtual std::string name() const = 0;
  virtual std::string description() const = 0;
  virtual std::vector<ParamDesc> params() const = 0;
  virtual ShadowBlockers shadow_blockers() const { return ShadowBlockers::SceneGeometry; }
  // The pass graph for this scene and settings. `empty` receives the resources that are empty for
  // this scene (no moving object, no re-radiating proxy, ...), so compile() leaves out their passes.
  virtual PassGraph plan(const scene::Scene& scene, const ParamSet& params, std::set<std::string>& empty) = 0;
  // The G-buffer planes (GBufferPlanes) this technique's passes read with these settings; the
  // visibility planes are always there. Every plane by default.
  virtual unsigned gbuffer_planes(const ParamSet& params) const {
    (void)params;
    return kGBufferAll;
  }
  // Frame resources that overlay() reads: a viewer that draws the overlay adds them to
  // RenderRequest::outputs. None by default.
  virtual std::vector<std::string> overlay_outputs() const { return {}; }
  // The overlay of a frame rendered with overlay_outputs() among its outputs.
  virtual OverlayGeometry overlay(const FrameResult& frame) const {
    (void)frame;
    return {};
  }
  // The paper figures this technique reproduces, for `softgi experiment` (none by default). Their
  // variants may name other registered techniques (a comparison figure).
  virtual std::vector<ExperimentDef> experiments() const { return {}; }
  // The large resources of a frame of width x height of this scene with these parameters, as
  // allocated by the technique's own passes (the shared passes' G-buffers and the composed image
  // are the framework's, a device backend's own buffers for the shared passes are the backend's).
  // Items of passes the compiled graph leaves out are not counted. None by default: such a
  // technique's frames are checked for the shared resources only.
  virtual std::vector<MemoryItem> estimate_memory(const scene::Scene& scene, const ParamSet& params, int width,
                                                  int height) const {
    (void)scene, (void)params, (void)width, (void)height;
    return {};
  }
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
