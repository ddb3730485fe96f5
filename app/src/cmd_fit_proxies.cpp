// `softgi fit-proxies`: bounding sphere sets for an object (paper 004 section 6.2), written as the
// proxy JSON that scene files reference.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

#include "commands.hpp"
#include "output_dir.hpp"
#include "softgi/io/gltf.hpp"
#include "softgi/io/proxy_fit.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/proxies/binding.hpp"
#include "softgi/proxies/sphere_fit.hpp"
#include "softgi/scene/builtin.hpp"

namespace softgi::app {

namespace {
struct FitArgs {
  std::string mesh;
  std::string output;
  std::string node;
  int spheres = 32;
  unsigned seed = 1;
  int iterations = 60;
  int grid = 32;
  bool octree = false;
};

bool has_gltf_extension(const std::string& path) {
  std::string lower = path;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  auto ends = [&](const std::string& e) { return lower.size() > e.size() && lower.compare(lower.size() - e.size(), e.size(), e) == 0; };
  return ends(".glb") || ends(".gltf");
}

// The object to fit: the named node, or else the closed mesh of largest volume (ground planes and
// other open surfaces have none).
int pick_node(const scene::Scene& s, const std::string& name, const std::string& source) {
  if (!name.empty()) {
    for (int i = 0; i < static_cast<int>(s.nodes.size()); ++i)
      if (s.nodes[i].name == name) {
        if (s.nodes[i].mesh < 0) throw std::invalid_argument(source + ": --node '" + name + "' has no mesh");
        return i;
      }
    std::string names;
    for (const scene::Node& n : s.nodes)
      if (n.mesh >= 0) names += (names.empty() ? "" : ", ") + ("'" + n.name + "'");
    throw std::invalid_argument(source + ": no node named '" + name + "' (nodes with a mesh: " + names + ")");
  }
  int best = -1;
  double best_volume = 0.0;
  std::string rejected;
  for (int i = 0; i < static_cast<int>(s.nodes.size()); ++i) {
    if (s.nodes[i].mesh < 0) continue;
    try {
      const double v = proxies::mesh_volume(proxies::trimesh_of(s.meshes[s.nodes[i].mesh]));
      if (v > best_volume) {
        best_volume = v;
        best = i;
      }
    } catch (const std::exception& e) {
      rejected += "\n  node '" + s.nodes[i].name + "': " + e.what();
    }
  }
  if (best < 0) throw std::invalid_argument(source + ": no node holds a closed mesh to bound" + rejected);
  return best;
}

void run_fit_proxies(const FitArgs& a) {
  OutputFile out(a.output, "-o");  // before the mesh is loaded and fitted
  scene::Scene s;
  std::string source = a.mesh;
  if (has_gltf_extension(a.mesh)) {
    io::load_gltf(a.mesh, s);
  } else {
    s = scene::make_builtin(a.mesh);  // names the known scenes when unknown
    source = "built-in scene '" + a.mesh + "'";
  }
  const int node = pick_node(s, a.node, source);
  const scene::Mesh& mesh = s.meshes[s.nodes[node].mesh];
  const proxies::TriMesh tri = proxies::trimesh_of(mesh);
  std::cout << "fit-proxies: " << source << ", node '" << s.nodes[node].name << "': " << tri.positions.size()
            << " vertices, " << tri.triangles.size() << " triangles\n";

  scene::ProxySet ps;
  ps.name = s.nodes[node].name;
  ps.node = node;
  std::cout << std::fixed;
  if (a.octree) {
    ps.spheres = proxies::octree_sphere_set(tri, a.spheres);
    ps.outside_volume_ratio = proxies::outside_volume_ratio(ps.spheres, tri);
    std::cout << "octree baseline: " << ps.spheres.size() << " spheres (at most " << a.spheres
              << "), E = " << std::setprecision(4) << ps.outside_volume_ratio << "\n";
  } else {
    proxies::FitOptions opt;
    opt.spheres = a.spheres;
    opt.seed = a.seed;
    opt.max_iterations = a.iterations;
    opt.grid_resolution = a.grid;
    const proxies::FitResult fit = proxies::fit_sphere_set(tri, opt, [](const proxies::FitProgress& p) {
      std::cout << "  iteration " << std::setw(3) << p.iteration << "  " << std::left << std::setw(8) << p.phase
                << std::right << "  E = " << std::setprecision(4) << p.E << std::endl;
    });
    ps.spheres = fit.spheres;
    ps.outside_volume_ratio = fit.E;
    std::cout << "fitted " << fit.spheres.size() << " spheres in " << fit.iterations << " iterations, "
              << std::setprecision(2) << fit.seconds << " s (teleports accepted " << fit.teleports_accepted << " of "
              << fit.teleports_tried << "); V(T) = " << std::setprecision(6) << fit.object_volume
              << "; E = sum V(S_i - T) / V(T) = " << std::setprecision(4) << fit.E << "\n";
  }
  if (mesh.skinned()) {
    const double err = proxies::bind_to_skin(ps, mesh);
    std::cout << "bound to the skin (mean value coordinates, 4 bones per sphere): reduction error " << std::scientific
              << std::setprecision(3) << err << " mesh units\n"
              << std::fixed;
  }
  // The albedo the proxies re-radiate with: the surface's (texture and vertex colours included),
  // averaged over each sphere's segment.
  io::average_surface_albedo(s, node, ps);
  std::cout << "albedo: surface average (" << std::setprecision(3) << ps.albedo.x << ", " << ps.albedo.y << ", " << ps.albedo.z
            << "), per sphere over its segment\n";
  out.write([&](const std::string& path) { io::write_proxies_json(path, ps); });
  std::cout << "wrote " << a.output << "\n";
}

void register_fit_proxies(CLI::App& app) {
  auto args = std::make_shared<FitArgs>();
  CLI::App* sub = app.add_subcommand("fit-proxies", "Fit a bounding sphere set to an object (paper 004 6.2) and write it as JSON");
  sub->add_option("mesh", args->mesh, "a .glb/.gltf file or a built-in scene name (e.g. bunny)")->required();
  sub->add_option("-o,--output", args->output, "output proxy JSON file")->required();
  sub->add_option("--spheres", args->spheres, "number of spheres")->check(CLI::Range(1, 100000));
  sub->add_option("--seed", args->seed, "random seed of the initial centres");
  sub->add_option("--iterations", args->iterations, "maximum iterations (clustering + sphere update)")
      ->check(CLI::Range(1, 100000));
  sub->add_option("--grid", args->grid, "interior voxel grid cells along the longest axis")->check(CLI::Range(1, 512));
  sub->add_option("--node", args->node, "name of the node to bound (default: the closed mesh of largest volume)");
  sub->add_flag("--octree", args->octree, "octree baseline instead of the variational fit (paper 004 Figure 4)");
  sub->callback([args] { run_fit_proxies(*args); });
}
const CommandRegistrar registrar(register_fit_proxies);
}  // namespace

}  // namespace softgi::app
