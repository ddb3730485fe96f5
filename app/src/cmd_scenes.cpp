// `softgi scenes`: the built-in scenes, whether their assets are present, and their sizes once built.
#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "commands.hpp"
#include "softgi/scene/builtin.hpp"

namespace softgi::app {

namespace {

struct ScenesArgs {
  bool json = false;
  bool no_build = false;
};

struct Counts {
  std::size_t triangles = 0, vertices = 0, objects = 0, proxy_sets = 0, proxy_spheres = 0, lights = 0, bones = 0;
  double clip_seconds = 0.0;
  double build_ms = 0.0;
};

Counts count(const scene::Scene& s) {
  Counts c;
  for (const auto& n : s.nodes)
    if (n.mesh >= 0) {
      c.triangles += s.meshes[n.mesh].triangles.size();
      c.vertices += s.meshes[n.mesh].positions.size();
      ++c.objects;
    }
  c.proxy_sets = s.proxies.size();
  for (const auto& p : s.proxies) c.proxy_spheres += p.spheres.size();
  c.lights = s.lights.size();
  for (const auto& sk : s.skins) c.bones += sk.joints.size();
  if (s.active_clip >= 0) c.clip_seconds = s.clips[s.active_clip].duration;
  return c;
}

// The asset a built-in scene needs (only bunny needs one today).
std::string needed_asset(const std::string& name) { return name == "bunny" ? scene::assets_dir() + "/models/bunny.glb" : ""; }

void run_scenes(const ScenesArgs& args) {
  nlohmann::json rows = nlohmann::json::array();
  int failures = 0;
  if (!args.json)
    std::cout << std::left << std::setw(13) << "scene" << std::right << std::setw(8) << "assets" << std::setw(11) << "triangles"
              << std::setw(9) << "vertices" << std::setw(9) << "objects" << std::setw(8) << "proxies" << std::setw(7) << "bones"
              << std::setw(7) << "lights" << std::setw(8) << "clip s" << std::setw(10) << "build ms" << "  description\n";
  for (const auto& info : scene::builtin_scenes()) {
    const std::string asset = needed_asset(info.name);
    const bool present = asset.empty() || std::filesystem::exists(asset);
    nlohmann::json row = {{"name", info.name}, {"description", info.description}, {"needs_assets", info.needs_assets}, {"assets_present", present}};
    std::string status = info.needs_assets ? (present ? "present" : "missing") : "-";
    Counts c;
    bool built = false;
    std::string error;
    if (!args.no_build && present) {
      try {
        const auto t0 = std::chrono::steady_clock::now();
        const scene::Scene s = scene::make_builtin(info.name);
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        scene::validate(s);
        c = count(s);
        c.build_ms = ms;
        built = true;
      } catch (const std::exception& e) {
        error = e.what();
        ++failures;
      }
    }
    if (built) {
      row["triangles"] = c.triangles;
      row["vertices"] = c.vertices;
      row["objects"] = c.objects;
      row["proxy_sets"] = c.proxy_sets;
      row["proxy_spheres"] = c.proxy_spheres;
      row["bones"] = c.bones;
      row["lights"] = c.lights;
      row["clip_seconds"] = c.clip_seconds;
      row["build_ms"] = c.build_ms;
    }
    if (!error.empty()) row["error"] = error;
    if (!present) row["missing"] = asset + " (run scripts/fetch-assets.sh)";
    rows.push_back(row);
    if (args.json) continue;
    std::cout << std::left << std::setw(13) << info.name << std::right << std::setw(8) << status;
    if (built) {
      std::cout << std::setw(11) << c.triangles << std::setw(9) << c.vertices << std::setw(9) << c.objects << std::setw(8) << c.proxy_spheres
                << std::setw(7) << c.bones << std::setw(7) << c.lights << std::setw(8) << std::fixed << std::setprecision(1) << c.clip_seconds
                << std::setw(10) << c.build_ms << std::defaultfloat;
    } else {
      std::cout << std::setw(77) << (args.no_build ? "" : "(not built)");
    }
    std::cout << "  " << info.description << "\n";
    if (!present) std::cout << "             missing " << asset << ": run scripts/fetch-assets.sh\n";
    if (!error.empty()) std::cout << "             error: " << error << "\n";
    std::cout << std::flush;  // one line per scene as it is built: the progress of a slow build
  }
  if (args.json) std::cout << nlohmann::json{{"assets_dir", scene::assets_dir()}, {"scenes", rows}}.dump(1) << "\n";
  else std::cout << "assets: " << scene::assets_dir() << "\n";
  if (failures > 0) throw std::runtime_error(std::to_string(failures) + " built-in scene(s) failed to build or validate (see above)");
}

void register_scenes(CLI::App& app) {
  auto args = std::make_shared<ScenesArgs>();
  CLI::App* sub = app.add_subcommand("scenes", "List the built-in scenes with their sizes (builds each one)");
  sub->add_flag("--json", args->json, "print JSON instead of the table");
  sub->add_flag("--no-build", args->no_build, "only list names, descriptions and asset presence");
  sub->callback([args] { run_scenes(*args); });
}
const CommandRegistrar registrar(register_scenes);

}  // namespace

}  // namespace softgi::app
