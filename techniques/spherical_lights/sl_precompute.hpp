// Spherical lights (paper 001): the per-object precomputation of sections 4.2 and 5.2. For each light
// (a sphere of the object's proxy set): its surface segment (eq. 2), its surface sample points (rays
// from its centre along geodesic directions, the paper's three cases), its albedo SH (the ray-cast
// equivalent of the paper's cube-map rendering) and the Voronoi basis sums of eq. 10. Not installed;
// include by path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/scene/scene.hpp"

namespace softgi::techniques::spherical_lights {

// Where the occlusion between intersecting lights of one object is taken into account.
// Precomputed (the paper, section 6.2): a light's sample points and albedo are its own segment's
// (rule 2 of section 4.2), so it emits nothing where an intersecting light's surface lies, and the
// receivers ignore intersecting lights as its blockers. RunTime: its sample points and albedo may
// also lie in the segments of the lights intersecting it, and the receivers resolve the occlusion
// per direction (only the ray-cast receiver pass can: the blocker function of an intersecting light
// is not circularly symmetric).
enum class IntersectingOcclusion { Precomputed, RunTime };

struct PrecomputeOptions {
  int order = 4;               // SH order n of intensities, albedo and basis sums (n^2 coefficients)
  int geodesic_frequency = 3;  // sample directions: 10 f^2 + 2 (f = 3: the paper's 92)
  int cubemap_resolution = 16; // albedo cube map, texels per face side
  int projection_strata = 64;  // eq. 9-10: N = strata^2 jittered stratified directions
  unsigned seed = 1;           // jitter of those directions
  IntersectingOcclusion intersecting = IntersectingOcclusion::Precomputed;
};

// Vertices of the geodesic sphere of frequency f >= 1 built on the icosahedron (each face cut into
// f^2 triangles, points pushed to the unit sphere): 10 f^2 + 2 unit vectors, each once. Order:
// the 12 icosahedron vertices, then the interior points of the 30 edges, then of the 20 faces.
std::vector<glm::vec3> geodesic_directions(int frequency);

// The N = strata^2 directions of eq. 9: z = 1 - 2u, phi = 2 pi v, one jittered (u, v) per cell of the
// strata x strata grid, row-major; std::mt19937(seed) (fixed by the standard, so reproducible).
std::vector<glm::dvec3> stratified_directions(int strata, unsigned seed);

// Index of the direction nearest to w (largest dot product; the lowest index on ties).
int nearest_direction(const std::vector<glm::vec3>& directions, const glm::dvec3& w);

// Eq. 10 with the 4 pi / N of eq. 9 folded in: per direction j, Y_j = (4 pi / N) sum over the
// stratified directions of its Voronoi cell of y(w_k) (order^2 values), and the cell counts N_j.
// L_S = sum_j L_pj Y_j is then eq. 9 for the nearest-neighbour function L_pj; the cells of discarded
// directions are left out of that sum (the light emits nothing there), which the per-sample copies in
// SphericalLightData::basis_sums do by holding kept samples only.
struct VoronoiBasis {
  int order = 0, total = 0;    // total: N
  std::vector<double> sums;    // directions x order^2
  std::vector<int> counts;     // N_j, summing to N
};
VoronoiBasis voronoi_basis_sums(const std::vector<glm::vec3>& directions, int order, int strata, unsigned seed);

// Eq. 2: d(p, S) = |p - x_S| / r_S.
double sl_distance(const glm::vec3& p, const scene::Sphere& s);
// The light whose segment holds p (smallest d, lowest index on ties).
int nearest_sl(const std::vector<scene::Sphere>& spheres, const glm::vec3& p);
// Whether p is in segment i: d(p, S_i) <= (1 + 1e-5) min_j d(p, S_j). The slack puts points within
// float rounding of a boundary (the bisecting planes of equal spheres) in both segments.
bool in_segment(const std::vector<scene::Sphere>& spheres, std::size_t i, const glm::vec3& p);

// How each geodesic direction of a light turned out (section 4.2's cases).
struct SampleOutcomes {
  int back_hit = 0;        // case 1: farthest back-side hit inside the segment -> sample point
  int occluded = 0;        // case 2: hits, none on a back side inside the segment -> discarded
  int opposite_front = 0;  // case 3: no hit; first front-side hit of -w inside the segment -> sample
  int missed = 0;          // case 3 without such a hit -> discarded
};
enum class SampleCase : std::uint8_t { BackHit = 1, OppositeFront = 3 };

struct SphericalLightData {
  scene::Sphere sphere;                    // rest pose, mesh space
  std::vector<glm::vec3> sample_positions; // mesh space
  std::vector<glm::vec3> sample_normals;   // interpolated vertex normals, unit, on the winding's outer side
  std::vector<int> sample_direction;       // geodesic direction index j of each sample
  std::vector<SampleCase> sample_case;
  std::vector<float> basis_sums;           // samples x order^2: Y_{sample_direction} (eq. 10, 4 pi / N folded in)
  std::vector<float> albedo_sh;            // 3 x order^2, channel-major (end of section 4.2)
  std::vector<std::uint32_t> vertices;     // mesh vertices whose nearest light this is (moves it at run time)
  std::vector<std::uint32_t> triangles;    // triangle set: a vertex in the segment (precomputation only)
  std::vector<int> intersecting;           // same-object lights with |c_i - c_j| < r_i + r_j
  SampleOutcomes outcomes;
  std::size_t sample_count() const { return sample_positions.size(); }
};

// A light bounding several of the set's lights (a parent of an SL hierarchy, paper 001 section 7.3):
// its sphere and the leaves (indices into the set's spheres) whose segments it takes together.
struct SlGroup {
  scene::Sphere sphere;
  std::vector<int> leaves;
};

struct ObjectSls {
  std::string proxy_set;
  int node = -1, mesh = -1, order = 0;
  std::vector<glm::vec3> directions;       // the geodesic directions w_j
  VoronoiBasis basis;                      // per direction, shared by every light of the object
  std::vector<SphericalLightData> sls;     // one per sphere of the proxy set, same order
  std::vector<SphericalLightData> groups;  // one per SlGroup asked for (no intersecting lists)
  // Bytes of the data the passes read per object (samples, basis sums, albedo, vertex lists,
  // intersecting lists, spheres, directions; not the triangle sets). The paper quotes 32-150 KB.
  std::size_t bytes() const;
};

// Precomputes the lights of one object from its rest mesh scene.meshes[scene.nodes[object_node].mesh]
// (mesh space = the space of set.spheres). Throws std::invalid_argument naming the proxy set for a bad
// node, an empty mesh, non-finite positions, no spheres, a sphere with radius <= 0 or non-finite values,
// or bad options.
// `groups`: lights made of several leaves each (section 7.3), computed with the same rules over the
// union of their leaves' segments and triangle sets, into ObjectSls::groups.
ObjectSls precompute_object(const scene::Scene& scene, int object_node, const scene::ProxySet& set,
                            const PrecomputeOptions& options = {}, const std::vector<SlGroup>* groups = nullptr);

}  // namespace softgi::techniques::spherical_lights
