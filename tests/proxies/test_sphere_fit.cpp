// Outside volume, mesh volume, the variational sphere-set fit and the octree baseline
// (paper 004 section 6.2 and Figure 4).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "meshes.hpp"
#include "softgi/proxies/sphere_fit.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::proxies {
namespace {

constexpr double kPi = std::numbers::pi;
double ball(double r) { return 4.0 / 3.0 * kPi * r * r * r; }

// The divergence-theorem volume of a box is exact up to double rounding of a dozen terms.
constexpr double kExactVolumeTol = 1e-12;
// sphere_outside_volume is a closed form; a centre on the surface is moved 4e-11 * (mesh diagonal)
// off it, which changes the volume by about pi r^2 * 1.4e-10 (relative < 1e-9 here).
constexpr double kClosedFormTol = 1e-9;
// Reference for random spheres against a box: nested Gauss-Legendre quadrature of the chord length
// with panels split at every kink; its own error is below 1e-7 relative (checked by halving).
constexpr double kQuadratureTol = 1e-6;

TEST(MeshVolume, BoxIsExact) {
  const TriMesh m = test::box_mesh({-1.0f, -0.5f, 0.25f}, {2.0f, 1.5f, 1.0f});
  EXPECT_NEAR(mesh_volume(m), 3.0 * 2.0 * 0.75, kExactVolumeTol * 4.5);
}

TEST(MeshVolume, UvSphereWithinTessellationBounds) {
  // An inscribed polyhedron: every face lies within a cap of angular radius delta (the largest
  // angular edge length), so it contains the ball of radius R cos(delta):
  //   4/3 pi (R cos delta)^3 <= V <= 4/3 pi R^3, and the deficit shrinks ~4x when delta halves.
  double previous_deficit = 0.0;
  for (int n : {16, 32, 64}) {
    const TriMesh m = test::uv_sphere_mesh(1.0f, n, 2 * n);
    const double delta = kPi / n;
    const double v = mesh_volume(m);
    EXPECT_LE(v, ball(1.0) * (1.0 + 1e-7)) << n;  // 1e-7: float vertex positions
    EXPECT_GE(v, ball(std::cos(delta))) << n;
    const double deficit = ball(1.0) - v;
    if (previous_deficit > 0.0) {
      EXPECT_NEAR(previous_deficit / deficit, 4.0, 0.2) << n;
    }
    previous_deficit = deficit;
  }
}

TEST(MeshVolume, RejectsBadMeshes) {
  TriMesh m = test::box_mesh({0, 0, 0}, {1, 1, 1});
  TriMesh inverted = m;
  for (auto& t : inverted.triangles) std::swap(t.y, t.z);
  EXPECT_THROW(mesh_volume(inverted), std::invalid_argument);
  TriMesh bad_index = m;
  bad_index.triangles[3].y = 99;
  EXPECT_THROW(mesh_volume(bad_index), std::invalid_argument);
  TriMesh nan = m;
  nan.positions[2].x = std::nanf("");
  EXPECT_THROW(mesh_volume(nan), std::invalid_argument);
  EXPECT_THROW(mesh_volume(TriMesh{}), std::invalid_argument);
}

TEST(SphereOutsideVolume, ClosedFormsAgainstABox) {
  const TriMesh box = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  auto out = [&](glm::vec3 c, float r) { return sphere_outside_volume(scene::Sphere{c, r}, box); };
  const double v = ball(0.5);
  EXPECT_NEAR(out({0, 0, 0}, 0.5f), 0.0, kClosedFormTol * v) << "inside";
  EXPECT_NEAR(out({0.25f, -0.25f, 0.5f}, 0.5f), 0.0, kClosedFormTol * v) << "inside, touching a face";
  EXPECT_NEAR(out({4, 0.5f, 0}, 0.5f), v, kClosedFormTol * v) << "outside";
  EXPECT_NEAR(out({1, 0, 0}, 0.5f), v / 2, kClosedFormTol * v) << "centred on a face";
  EXPECT_NEAR(out({1, 1, 0}, 0.5f), v * 3 / 4, kClosedFormTol * v) << "centred on an edge";
  EXPECT_NEAR(out({1, -1, 1}, 0.5f), v * 7 / 8, kClosedFormTol * v) << "centred on a corner";
  EXPECT_NEAR(out({0, 0, 0}, 0.0f), 0.0, 0.0) << "zero radius";
  // One face cuts a cap of height h = r - (1 - x) off the sphere: pi h^2 (3r - h) / 3.
  const double r = 0.75, h = 0.25;
  const double cap = kPi * h * h * (3 * r - h) / 3;
  EXPECT_NEAR(out({0.5f, 0, 0}, 0.75f), cap, kClosedFormTol * ball(r)) << "cap, centre inside";
  EXPECT_NEAR(out({1.5f, 0, 0}, 0.75f), ball(r) - cap, kClosedFormTol * ball(r)) << "cap, centre outside";
  // A sphere containing the box.
  EXPECT_NEAR(out({0.25f, 0.5f, -0.125f}, 3.0f), ball(3) - 8, kClosedFormTol * ball(3));
  EXPECT_NEAR(out({1.5f, 0.5f, -0.125f}, 5.0f), ball(5) - 8, kClosedFormTol * ball(5)) << "centre outside";
}

// V(B(c, r) ∩ [-1,1]^3) by quadrature of the chord length in z over (x, y).
double ball_box_reference(glm::dvec3 c, double r) {
  // Gauss-Legendre, 16 points on [-1, 1].
  static const double xg[8] = {0.0950125098376374, 0.2816035507792589, 0.4580167776572274, 0.6178762444026438,
                               0.7554044083550030, 0.8656312023878318, 0.9445750230732326, 0.9894009349916499};
  static const double wg[8] = {0.1894506104550685, 0.1826034150449236, 0.1691565193950025, 0.1495959888165767,
                               0.1246289712555339, 0.0951585116824928, 0.0622535239386479, 0.0271524594117541};
  auto integrate = [&](double a, double b, int panels, auto&& f) {
    double s = 0.0;
    for (int p = 0; p < panels; ++p) {
      const double lo = a + (b - a) * p / panels, hi = a + (b - a) * (p + 1) / panels;
      const double m = 0.5 * (lo + hi), hw = 0.5 * (hi - lo);
      for (int k = 0; k < 8; ++k) s += wg[k] * hw * (f(m - hw * xg[k]) + f(m + hw * xg[k]));
    }
    return s;
  };
  // Splits [a, b] at the given kinks and integrates each piece; substitution t = sin keeps the
  // square-root ends of circle chords smooth.
  auto split = [&](double a, double b, std::vector<double> kinks, auto&& f) {
    kinks.push_back(a);
    kinks.push_back(b);
    std::sort(kinks.begin(), kinks.end());
    double s = 0.0;
    for (size_t i = 0; i + 1 < kinks.size(); ++i) {
      const double lo = std::clamp(kinks[i], a, b), hi = std::clamp(kinks[i + 1], a, b);
      if (hi > lo) s += integrate(lo, hi, 24, f);
    }
    return s;
  };
  auto chord = [&](double x, double y) {
    const double s2 = r * r - (x - c.x) * (x - c.x) - (y - c.y) * (y - c.y);
    if (s2 <= 0.0) return 0.0;
    const double s = std::sqrt(s2);
    return std::max(0.0, std::min(1.0, c.z + s) - std::max(-1.0, c.z - s));
  };
  // Kinks in x: where the slice circle starts to meet a face or an edge of the box.
  std::vector<double> kx{c.x};
  for (double dy : {-1.0 - c.y, 1.0 - c.y, 0.0})
    for (double dz : {-1.0 - c.z, 1.0 - c.z, 0.0}) {
      const double q = r * r - dy * dy - dz * dz;
      if (q > 0.0) {
        kx.push_back(c.x - std::sqrt(q));
        kx.push_back(c.x + std::sqrt(q));
      }
    }
  return split(std::max(-1.0, c.x - r), std::min(1.0, c.x + r), kx, [&](double x) {
    const double rho2 = r * r - (x - c.x) * (x - c.x);
    if (rho2 <= 0.0) return 0.0;
    const double rho = std::sqrt(rho2);
    // Kinks in y: where the chord starts to reach the z faces.
    std::vector<double> k{c.y};
    for (double zf : {-1.0, 1.0}) {
      const double dz = zf - c.z;
      const double q = rho2 - dz * dz;
      if (q > 0.0) {
        k.push_back(c.y - std::sqrt(q));
        k.push_back(c.y + std::sqrt(q));
      }
    }
    return split(std::max(-1.0, c.y - rho), std::min(1.0, c.y + rho), k, [&](double y) { return chord(x, y); });
  });
}

TEST(SphereOutsideVolume, MatchesQuadratureForRandomSpheres) {
  const TriMesh box = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(-1.8f, 1.8f), R(0.1f, 1.5f);
  for (int i = 0; i < 40; ++i) {
    const scene::Sphere s{{U(rng), U(rng), U(rng)}, R(rng)};
    const double ref = ball(s.radius) - ball_box_reference(glm::dvec3(s.center), s.radius);
    EXPECT_NEAR(sphere_outside_volume(s, box), ref, kQuadratureTol * ball(s.radius))
        << "centre " << s.center.x << " " << s.center.y << " " << s.center.z << " r " << s.radius;
  }
}

TEST(SphereOutsideVolume, ConcentricWithATessellatedSphere) {
  // A sphere containing a closed mesh: V(S - T) = V(S) - V(T) whatever the tessellation.
  const TriMesh m = test::uv_sphere_mesh(1.0f, 12, 24);
  const double vt = mesh_volume(m);
  EXPECT_NEAR(sphere_outside_volume({{0.01f, 0.02f, -0.03f}, 1.25f}, m), ball(1.25) - vt, kClosedFormTol * ball(1.25));
  // A small sphere deep inside: nothing outside.
  EXPECT_NEAR(sphere_outside_volume({{0.1f, 0.0f, 0.0f}, 0.5f}, m), 0.0, kClosedFormTol * ball(0.5));
}

TEST(SphereOutsideVolume, RejectsOpenMeshesAndBadSpheres) {
  TriMesh open = test::box_mesh({0, 0, 0}, {1, 1, 1});
  open.triangles.pop_back();
  EXPECT_THROW(sphere_outside_volume({{0, 0, 0}, 1.0f}, open), std::invalid_argument);
  const TriMesh box = test::box_mesh({0, 0, 0}, {1, 1, 1});
  EXPECT_THROW(sphere_outside_volume({{0, 0, 0}, -1.0f}, box), std::invalid_argument);
  EXPECT_THROW(sphere_outside_volume({{0, std::nanf(""), 0}, 1.0f}, box), std::invalid_argument);
}

TEST(OutsideVolumeRatio, SumsSpheres) {
  const TriMesh box = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  const std::vector<scene::Sphere> s{{{4, 0, 0}, 0.5f}, {{1, 0, 0}, 0.5f}};
  EXPECT_NEAR(outside_volume_ratio(s, box), 1.5 * ball(0.5) / 8.0, kClosedFormTol);
}

// ---- The fit ----

// Every point is inside some sphere in double arithmetic on the stored float values: no slack.
void expect_bounds_all(const std::vector<scene::Sphere>& spheres, const std::vector<glm::dvec3>& pts, const char* what) {
  size_t missed = 0;
  for (const glm::dvec3& p : pts) {
    bool in = false;
    for (const scene::Sphere& s : spheres)
      if (glm::length(p - glm::dvec3(s.center)) <= static_cast<double>(s.radius)) {
        in = true;
        break;
      }
    missed += !in;
  }
  EXPECT_EQ(missed, 0u) << what << ": " << missed << " of " << pts.size() << " points are outside every sphere";
}

TEST(FitSphereSet, BoundsEveryPointAndLowersE) {
  const TriMesh m = test::blob_mesh(16, 32);
  FitOptions opt;
  opt.spheres = 6;
  opt.grid_resolution = 16;
  opt.max_iterations = 10;
  double first_E = -1.0;
  int calls = 0;
  const FitResult r = fit_sphere_set(m, opt, [&](const FitProgress& p) {
    if (calls++ == 0) {
      EXPECT_EQ(p.phase, "cluster");
      first_E = p.E;  // the first bounding state: clustering around the random initial centres
    }
    EXPECT_TRUE(std::isfinite(p.E));
  });
  ASSERT_EQ(r.spheres.size(), 6u);
  EXPECT_GE(calls, 2);
  EXPECT_GT(first_E, 0.0);
  EXPECT_LT(r.E, 0.5 * first_E) << "the variational iterations must at least halve E from the first clustering";
  EXPECT_NEAR(r.E, outside_volume_ratio(r.spheres, m), 1e-12) << "reported E is the E of the returned spheres";
  EXPECT_NEAR(r.object_volume, mesh_volume(m), 1e-9 * r.object_volume);
  expect_bounds_all(r.spheres, fit_sample_points(m, opt), "sample points");
  std::vector<glm::dvec3> verts(m.positions.begin(), m.positions.end());
  expect_bounds_all(r.spheres, verts, "mesh vertices");
  // The octree at the same count is far looser (paper 004 Figure 4).
  const std::vector<scene::Sphere> oct = octree_sphere_set(m, 6);
  EXPECT_LT(2.0 * r.E, outside_volume_ratio(oct, m));
}

TEST(FitSphereSet, RandomSurfaceSamplesAreBoundedToo) {
  const TriMesh m = test::uv_sphere_mesh(1.0f, 10, 20);
  FitOptions opt;
  opt.spheres = 3;
  opt.surface_points = 400;
  opt.grid_resolution = 8;
  opt.max_iterations = 4;
  const std::vector<glm::dvec3> pts = fit_sample_points(m, opt);
  opt.surface_points = 0;
  const size_t with_midpoints = fit_sample_points(m, opt).size();
  // Vertices + 400 samples + interior corners versus vertices + one midpoint per triangle + the same corners.
  EXPECT_EQ(pts.size() + m.triangles.size(), with_midpoints + 400);
  for (size_t i = m.positions.size(); i < m.positions.size() + 400; ++i)
    EXPECT_NEAR(glm::length(pts[i]), 1.0, 0.05) << "surface sample " << i << " is on the tessellated unit sphere";
  opt.surface_points = 400;
  expect_bounds_all(fit_sphere_set(m, opt).spheres, pts, "random surface samples");
}

TEST(FitSphereSet, IsDeterministic) {
  const TriMesh m = test::blob_mesh(12, 24);
  FitOptions opt;
  opt.spheres = 4;
  opt.grid_resolution = 10;
  opt.max_iterations = 4;
  opt.seed = 3;
  const FitResult a = fit_sphere_set(m, opt), b = fit_sphere_set(m, opt);
  ASSERT_EQ(a.spheres.size(), b.spheres.size());
  for (size_t i = 0; i < a.spheres.size(); ++i) {
    EXPECT_EQ(a.spheres[i].center, b.spheres[i].center);
    EXPECT_EQ(a.spheres[i].radius, b.spheres[i].radius);
  }
  EXPECT_EQ(a.E, b.E);
}

TEST(FitSphereSet, OneSphereAroundASphereMeshCostsOnlyTheTessellation) {
  // The best single bounding sphere of an inscribed UV sphere is the circumsphere: E = V(S)/V(T) - 1.
  const TriMesh m = test::uv_sphere_mesh(1.0f, 16, 32);
  const double tessellation = ball(1.0) / mesh_volume(m) - 1.0;
  FitOptions opt;
  opt.spheres = 1;
  opt.grid_resolution = 12;
  opt.max_iterations = 6;
  const FitResult r = fit_sphere_set(m, opt);
  ASSERT_EQ(r.spheres.size(), 1u);
  EXPECT_GE(r.E, tessellation * (1.0 - 1e-6));
  // Powell's line searches stop at 1e-2 of the step: allow 2% of the (small) tessellation error.
  EXPECT_LE(r.E, tessellation * 1.02);
}

TEST(FitSphereSet, RejectsBadOptionsAndMeshes) {
  const TriMesh m = test::box_mesh({0, 0, 0}, {1, 1, 1});
  FitOptions opt;
  opt.spheres = 0;
  EXPECT_THROW(fit_sphere_set(m, opt), std::invalid_argument);
  opt.spheres = 2;
  opt.grid_resolution = 0;
  EXPECT_THROW(fit_sphere_set(m, opt), std::invalid_argument);
  opt.grid_resolution = 4;
  opt.spheres = 1000000;
  EXPECT_THROW(fit_sphere_set(m, opt), std::invalid_argument) << "more spheres than sample points";
  opt.spheres = 2;
  opt.stall_tolerance = std::nan("");
  EXPECT_THROW(fit_sphere_set(m, opt), std::invalid_argument);
  TriMesh open = m;
  open.triangles.erase(open.triangles.begin());
  EXPECT_THROW(fit_sphere_set(open, FitOptions{}), std::invalid_argument);
}

TEST(FitSphereSet, RejectsOverlappingParts) {
  // Two closed boxes that overlap: each is closed, but the region they share has winding number 2,
  // where the signed triangle sums would count the volume twice.
  TriMesh two = test::box_mesh({0, 0, 0}, {2, 1, 1});
  const TriMesh other = test::box_mesh({1, 0.25f, 0.25f}, {3, 0.75f, 0.75f});
  const unsigned base = static_cast<unsigned>(two.positions.size());
  two.positions.insert(two.positions.end(), other.positions.begin(), other.positions.end());
  for (const glm::uvec3& t : other.triangles) two.triangles.push_back(t + glm::uvec3(base));
  FitOptions opt;
  opt.spheres = 2;
  opt.grid_resolution = 12;
  EXPECT_THROW(fit_sphere_set(two, opt), std::invalid_argument);
  EXPECT_THROW(octree_sphere_set(two, 16), std::invalid_argument);
  // Disjoint closed parts are fine.
  TriMesh apart = test::box_mesh({0, 0, 0}, {1, 1, 1});
  const TriMesh far = test::box_mesh({2, 0, 0}, {3, 1, 1});
  apart.positions.insert(apart.positions.end(), far.positions.begin(), far.positions.end());
  for (const glm::uvec3& t : far.triangles) apart.triangles.push_back(t + glm::uvec3(8));
  const FitResult r = fit_sphere_set(apart, opt);
  EXPECT_NEAR(r.object_volume, 2.0, 1e-12);
  expect_bounds_all(r.spheres, fit_sample_points(apart, opt), "two disjoint boxes");
}

TEST(FitSphereSet, WeldsSeamsOfASceneMesh) {
  // glTF splits vertices along seams: the same box with every face's corners duplicated.
  const TriMesh box = test::box_mesh({0, 0, 0}, {1, 2, 1});
  scene::Mesh mesh;
  mesh.name = "split box";
  for (const glm::uvec3& t : box.triangles) {
    const unsigned base = static_cast<unsigned>(mesh.positions.size());
    for (int k = 0; k < 3; ++k) mesh.positions.push_back(box.positions[t[k]]);
    mesh.triangles.push_back({base, base + 1, base + 2});
  }
  const TriMesh welded = trimesh_of(mesh);
  EXPECT_EQ(welded.positions.size(), 8u);
  EXPECT_EQ(welded.triangles.size(), 12u);
  FitOptions opt;
  opt.spheres = 2;
  opt.grid_resolution = 6;
  opt.max_iterations = 3;
  EXPECT_NO_THROW(fit_sphere_set(welded, opt));
}

// ---- Octree baseline ----

TEST(OctreeSphereSet, CoversEveryPointWithinTheCount) {
  const TriMesh m = test::blob_mesh(16, 32);
  FitOptions grid;
  grid.grid_resolution = 20;
  const std::vector<glm::dvec3> pts = fit_sample_points(m, grid);
  for (int count : {1, 8, 30, 64}) {
    const std::vector<scene::Sphere> s = octree_sphere_set(m, count);
    EXPECT_GE(s.size(), 1u);
    EXPECT_LE(s.size(), static_cast<size_t>(count));
    if (count >= 8) {
      EXPECT_GE(s.size(), static_cast<size_t>(count) - 7) << "stops only when no cell fits";
    }
    expect_bounds_all(s, pts, "octree");
  }
  EXPECT_THROW(octree_sphere_set(m, 0), std::invalid_argument);
}

}  // namespace
}  // namespace softgi::proxies
