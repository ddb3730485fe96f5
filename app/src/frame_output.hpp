// What `softgi render` and `softgi compare` share: backends, parameters, and the JSON run record generated
// from a FrameResult and a ParamSet (files are written through OutputDir, output_dir.hpp).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "output_dir.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/scene.hpp"

namespace CLI {
class App;
}

namespace softgi::app {

// Records keep insertion order (parameters in description order, fields as written).
using Json = nlohmann::ordered_json;

// The scene of --scene / --fit-proxies (commands.hpp SceneArgs), its notices printed as COMMAND's.
scene::Scene load_cli_scene(const std::string& command, const std::string& spec, int fit_proxies);

// Registers every backend and technique this build has (idempotent); every command calls it first.
void register_builtin();
// Backends the CLI can run (--backend): the registered ones. Errors name the backend and list the
// available ones.
std::string check_backend(const std::string& name);
// "cpu (description), vulkan (description); default: cpu" for --help texts.
std::string backends_help();
// The items of a comma-separated list, trimmed of blanks; empty items are dropped.
std::vector<std::string> split_list(const std::string& s);
// A comma-separated list of backends ("cpu,vulkan"), each checked, without duplicates.
std::vector<std::string> parse_backends(const std::string& list);
// The backend `name`; `device` (--device NAME|INDEX) selects the device of a backend that has one
// and is an error for the others. The device chosen is printed on stderr.
std::unique_ptr<render::Backend> make_backend(const std::string& name, const std::string& device, const std::string& command);
// What a record says about the device a frame ran on (Backend::device_record): {} for the CPU
// backend; name, type, driver, API version, ids and validation state for the Vulkan backend.
Json device_json(const render::Backend& backend);

// The user's --param list names each parameter once (a repeated one is an error naming both values,
// not a silent last-wins).
void check_distinct_params(const std::vector<std::string>& assignments);
// A technique's parameters, defaults overridden by "name=value" assignments (errors name the
// technique and the parameter).
render::ParamSet technique_params(const render::Technique& t, const std::vector<std::string>& assignments);

// The SH order a technique's image is compared against: its "order" parameter, or paper 004's
// Figure 7 order for a technique that has none.
inline constexpr int kDefaultShOrder = 4;
int sh_order_of(const render::ParamSet& p);

// Parameter values typed by their descriptions (int, float, bool, enum as string), in description order.
Json params_json(const render::ParamSet& params);
// passes, pruned, total_seconds, bytes, transfer_bytes, peak_rss_bytes, warnings of a frame.
Json frame_json(const render::FrameResult& r);
// A record's "scene": name, source, the spec the user gave (--scene), what loading noted.
Json scene_json(const scene::Scene& sc, const std::string& spec);
// Scene::notices ("COMMAND: note: ...") and FrameResult::warnings ("COMMAND: warning: TECHNIQUE:
// ...") on stderr, one line each, so what a record keeps is also seen when it happens.
void print_scene_notices(const std::string& command, const scene::Scene& sc);
void print_frame_warnings(const std::string& command, const render::FrameResult& r);
// "0.1.0" and an ISO 8601 UTC timestamp.
std::string softgi_version();
std::string utc_now();

// A camera placed on the command line (softgi render; the viewer's screenshots name these options so
// that the frame can be rendered again): each vector "x,y,z", the field of view in degrees. Empty /
// 0: the scene camera's.
struct CameraArgs {
  std::string position, target, up;
  double fov_y_deg = 0.0;
};
void add_camera_options(CLI::App& sub, CameraArgs& args);
// Sets what `args` gives on `camera`; errors name the option and the text (three finite numbers; a
// field of view inside (0, 179) degrees).
void apply_camera_args(const CameraArgs& args, scene::Camera& camera);
// "x,y,z" with enough digits that a float reads back to the same value.
std::string format_vec3(const glm::vec3& v);
// The camera a frame was rendered from: position, target, up, fov_y_deg.
Json camera_json(const scene::Camera& c);

// `s` as one word of a POSIX shell command (single-quoted unless it is plain).
std::string shell_quote(const std::string& s);

// What a frame of `softgi render` is, to render it again: the command line that renders `sc` (loaded
// from `spec`, with --fit-proxies `fit_proxies` when non-zero) with its camera, the technique's
// non-default parameters, the backend, the time and the size, writing to `out`. Arguments are
// quoted for a POSIX shell.
std::string render_command_line(const std::string& spec, int fit_proxies, const scene::Scene& sc, const std::string& technique,
                                const render::ParamSet& params, const std::string& backend, double time, int width, int height,
                                const std::string& out);
// Writes a frame's final, direct and indirect images (those it has) to `out` as NAME.exr and a
// tone-mapped NAME.png; returns what a record lists under "images": {name: {exr, png}} for the files
// written (a file that failed is under outputs.missing instead).
Json write_frame_images(OutputDir& out, const render::FrameResult& r);

// The run record of one rendered frame, the form `softgi render` writes and the viewer's screenshots
// share: version, date, command, the command line that renders it again, scene, camera, technique,
// backend, device, parameters, time, resolution, `images` (name -> {exr, png}) and frame_json(r).
Json render_record(const std::string& command, const std::string& spec, int fit_proxies, const scene::Scene& sc,
                   const render::Technique& technique, const render::Backend& backend, const render::ParamSet& params,
                   double time, int width, int height, const Json& images, const render::FrameResult& r, const std::string& out);

// "--help" footer: every registered technique with its parameter descriptions.
std::string techniques_help();

}  // namespace softgi::app
