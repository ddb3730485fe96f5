// `softgi render`: one frame of one technique on one scene; images and a JSON run record.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "frame_output.hpp"
#include "output_dir.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/techniques/registry.hpp"

namespace softgi::app {

namespace {

struct RenderArgs {
  SceneArgs scene;
  CameraArgs camera;
  std::string technique, backend, device, out;  // backend: "" = the reference backend
  std::vector<std::string> params;
  double frame = 0.0;
  int width = 0, height = 0;
};

void run_render(const RenderArgs& args) {
  register_builtin();
  const std::string backend_name = args.backend.empty() ? render::reference_backend_name() : args.backend;
  check_backend(backend_name);
  if (!args.device.empty() && !render::backend_info(backend_name).selects_device)
    throw std::invalid_argument("--device '" + args.device + "': the " + backend_name + " backend selects no device");
  if (!std::isfinite(args.frame)) throw std::invalid_argument("--frame: time must be finite");
  // Cheap checks first: an unknown technique or parameter fails before the scene is loaded.
  std::unique_ptr<render::Technique> technique = render::create_technique(args.technique);
  check_distinct_params(args.params);
  const render::ParamSet params = technique_params(*technique, args.params);
  OutputDir out(args.out, "--out", "record.json");  // before the device, the scene and the frame
  std::unique_ptr<render::Backend> backend_ptr = make_backend(backend_name, args.device, "render");  // device errors early
  render::Backend& backend = *backend_ptr;
  scene::Scene sc = load_cli_scene("render", args.scene.spec, args.scene.fit_proxies);
  apply_camera_args(args.camera, sc.camera);
  int w = args.width, h = args.height;
  render::resolve_resolution(sc.camera, w, h);
  render::make_pinhole_camera(sc, w, h, "render");  // camera and size errors before any work

  std::cerr << "render: " << technique->name() << " on '" << sc.name << "' at " << w << "x" << h << ", t = " << args.frame
            << " s\n";
  render::RenderRequest req;
  req.time = args.frame;
  req.width = w;
  req.height = h;
  req.outputs = {"final"};
  const render::FrameResult r = backend.render(*technique, sc, params, req);
  if (r.final_image.empty())
    throw std::runtime_error("render: technique '" + technique->name() + "' produced no final image");
  print_frame_warnings("render", r);

  const Json images = write_frame_images(out, r);

  out.finish(render_record("render", args.scene.spec, args.scene.fit_proxies, sc, *technique, backend, params, args.frame, w, h,
                           images, r, args.out));

  std::cerr << "render: " << r.passes.size() << " passes in " << r.total_seconds * 1e3 << " ms (";
  for (std::size_t i = 0; i < r.passes.size(); ++i)
    std::cerr << (i ? ", " : "") << r.passes[i].name << " " << r.passes[i].wall_seconds * 1e3 << " ms"
              << (r.passes[i].gpu_seconds >= 0.0 ? " (GPU " + std::to_string(r.passes[i].gpu_seconds * 1e3) + " ms)" : "");
  std::cerr << "); " << r.pruned.size() << " pruned; wrote " << args.out << "\n";
}

void register_render(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* sub = app.add_subcommand("render", "Render one frame of a technique: final/direct/indirect EXR + PNG and record.json");
  add_scene_options(*sub, args->scene);
  sub->add_option("--technique", args->technique, "technique name (softgi techniques lists them)")->required();
  sub->add_option("--param", args->params, "technique parameter NAME=VALUE (repeatable)");
  add_camera_options(*sub, args->camera);
  sub->add_option("--frame", args->frame, "animation time in seconds (default 0)");
  sub->add_option("--width", args->width, "image width (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--height", args->height, "image height (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--backend", args->backend, "backend: " + backends_help());
  sub->add_option("--device", args->device,
                  "Vulkan device: index or name substring (default: $SOFTGI_VULKAN_DEVICE, else a GPU, else lavapipe)");
  sub->add_option("--out", args->out, "output directory")->required();
  sub->footer([] { return techniques_help(); });  // lazily: only --help pays for creating every technique
  sub->callback([args] { run_render(*args); });
}
const CommandRegistrar registrar(register_render);

}  // namespace

}  // namespace softgi::app
