// Bounding sphere sets for blocker geometry (paper 004 section 6.2, after Wang et al. 2006).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "softgi/scene/scene.hpp"

namespace softgi::proxies {

// A closed triangle mesh (rest pose) to be bounded.
struct TriMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::uvec3> triangles;
};
TriMesh trimesh_of(const scene::Mesh& mesh);

// Volume enclosed by a closed mesh (divergence theorem); throws if the mesh is not closed enough to
// give a positive volume.
double mesh_volume(const TriMesh& mesh);
// V(S - T): volume of the sphere outside the mesh (paper 004 eq. 35 term), by the signed
// outside-volume sum over triangles of Wang et al. 2006 or an equivalent exact-to-tolerance method.
double sphere_outside_volume(const scene::Sphere& s, const TriMesh& mesh);
// E = sum_i V(S_i - T) / V(T) (paper 004 Figure 4 caption).
double outside_volume_ratio(const std::vector<scene::Sphere>& spheres, const TriMesh& mesh);

struct FitOptions {
  int spheres = 32;
  int surface_points = 0;         // 0: triangle midpoints (paper)
  int grid_resolution = 32;       // interior voxel grid along the longest axis (paper: grid corners)
  int max_iterations = 60;
  int teleport_after_stall = 3;   // iterations without significant E reduction before teleporting
  double stall_tolerance = 1e-3;  // relative E reduction counted as significant
  unsigned seed = 1;
};
struct FitProgress {
  int iteration = 0;
  double E = 0.0;
  std::string phase;  // "cluster", "update", "teleport"
};
struct FitResult {
  std::vector<scene::Sphere> spheres;
  double E = 0.0;
  double object_volume = 0.0;
  int iterations = 0;
  int teleports_accepted = 0, teleports_tried = 0;
  double seconds = 0.0;
};
// The points the fit bounds (and clusters): the mesh vertices, the surface samples (triangle
// midpoints, or opt.surface_points random area-weighted samples) and the corners of the voxel grid
// (opt.grid_resolution cells along the longest axis) that lie inside the mesh. Deterministic.
std::vector<glm::dvec3> fit_sample_points(const TriMesh& mesh, const FitOptions& opt);

// Variational fit: surface and interior points, flood-fill clustering, per-cluster sphere update
// minimising outside volume while bounding the cluster (Powell's method), cluster teleportation.
// Every point of fit_sample_points(mesh, opt) is inside some sphere on return. Without a
// `progress` callback, a fit that runs past the delay reports on softgi::Progress
// (softgi/progress.hpp); with one, only the callback hears of the iterations.
FitResult fit_sphere_set(const TriMesh& mesh, const FitOptions& opt,
                         const std::function<void(const FitProgress&)>& progress = {});

// Baseline (paper 004 Figure 4 "octree"): bounding spheres of the occupied cells of an octree,
// refined until `count` spheres; every mesh point is covered.
std::vector<scene::Sphere> octree_sphere_set(const TriMesh& mesh, int count);

}  // namespace softgi::proxies
