// Bounding sphere sets (paper 004 section 6.2, after Wang, Zhou, Snyder et al. 2006 "Variational
// sphere set approximation for solid objects"), the octree baseline of paper 004 Figure 4, and
// Powell's method (shared with hierarchy.cpp through detail.hpp).
#include "softgi/proxies/sphere_fit.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <queue>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "detail.hpp"
#include "softgi/progress.hpp"

namespace softgi::proxies {

namespace detail {

float round_radius_up(double r) {
  float f = static_cast<float>(r);
  if (static_cast<double>(f) < r) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

namespace {
constexpr double kGold = 1.618034;
constexpr double kCGold = 0.3819660;

// Brent's method on a bracket ax < bx < cx (or reversed) with f(bx) <= f(ax), f(cx); returns the
// abscissa of the minimum found and stores its value in fmin (Numerical Recipes 10.2).
double brent(const std::function<double(double)>& f, double ax, double bx, double cx, double fbx, double tol,
             int max_iter, double& fmin) {
  constexpr double kZeps = 1e-12;
  double a = std::min(ax, cx), b = std::max(ax, cx);
  double x = bx, w = bx, v = bx, fx = fbx, fw = fbx, fv = fbx;
  double d = 0.0, e = 0.0;
  for (int it = 0; it < max_iter; ++it) {
    const double xm = 0.5 * (a + b);
    const double tol1 = tol * std::abs(x) + kZeps, tol2 = 2.0 * tol1;
    if (std::abs(x - xm) <= tol2 - 0.5 * (b - a)) break;
    if (std::abs(e) > tol1) {
      const double r = (x - w) * (fx - fv);
      double q = (x - v) * (fx - fw);
      double p = (x - v) * q - (x - w) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      const double etemp = e;
      e = d;
      if (std::abs(p) >= std::abs(0.5 * q * etemp) || p <= q * (a - x) || p >= q * (b - x)) {
        e = x >= xm ? a - x : b - x;
        d = kCGold * e;
      } else {
        d = p / q;
        const double u = x + d;
        if (u - a < tol2 || b - u < tol2) d = std::copysign(tol1, xm - x);
      }
    } else {
      e = x >= xm ? a - x : b - x;
      d = kCGold * e;
    }
    const double u = std::abs(d) >= tol1 ? x + d : x + std::copysign(tol1, d);
    const double fu = f(u);
    if (fu <= fx) {
      if (u >= x) a = x; else b = x;
      v = w; w = x; x = u;
      fv = fw; fw = fx; fx = fu;
    } else {
      if (u < x) a = u; else b = u;
      if (fu <= fw || w == x) {
        v = w; w = u; fv = fw; fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u; fv = fu;
      }
    }
  }
  fmin = fx;
  return x;
}

// Minimises f(p + t dir) over t from the bracket (0, 1), moves p there and rescales dir by the step.
void line_minimize(const std::function<double(const glm::dvec3&)>& f, glm::dvec3& p, glm::dvec3& dir, double& fp,
                   double tol) {
  auto phi = [&](double t) { return f(p + t * dir); };
  double ax = 0.0, bx = 1.0, fa = fp, fb = phi(bx);
  if (fb > fa) {
    std::swap(ax, bx);
    std::swap(fa, fb);
  }
  double cx = bx + kGold * (bx - ax), fc = phi(cx);
  for (int guard = 0; fb > fc && guard < 24; ++guard) {
    ax = bx; fa = fb;
    bx = cx; fb = fc;
    cx = bx + kGold * (bx - ax);
    fc = phi(cx);
  }
  double fmin = fb;
  const double t = brent(phi, ax, bx, cx, fb, tol, 30, fmin);
  if (fmin < fp) {
    p += t * dir;
    fp = fmin;
    if (std::abs(t) > 1e-3) dir *= t;
  }
}
}  // namespace

PowellResult powell_minimize(const std::function<double(const glm::dvec3&)>& f, const glm::dvec3& x0, double step,
                             double ftol, double line_tol, int max_sweeps, int max_evaluations) {
  PowellResult res;
  auto counted = [&](const glm::dvec3& x) {
    ++res.evaluations;
    return f(x);
  };
  std::function<double(const glm::dvec3&)> F = counted;
  glm::dvec3 p = x0, pt = x0;
  double fret = F(p);
  glm::dvec3 xi[3] = {{step, 0, 0}, {0, step, 0}, {0, 0, step}};
  for (int sweep = 0; sweep < max_sweeps && res.evaluations < max_evaluations; ++sweep) {
    if (fret == 0.0) break;  // objectives here are >= 0: nothing left to gain
    const double fp = fret;
    int ibig = 0;
    double del = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double fptt = fret;
      line_minimize(F, p, xi[i], fret, line_tol);
      if (fptt - fret > del) {
        del = fptt - fret;
        ibig = i;
      }
    }
    if (2.0 * (fp - fret) <= ftol * (std::abs(fp) + std::abs(fret)) + 1e-300) break;
    const glm::dvec3 ptt = 2.0 * p - pt;
    glm::dvec3 xit = p - pt;
    pt = p;
    const double fptt = F(ptt);
    if (fptt < fp) {
      const double t = 2.0 * (fp - 2.0 * fret + fptt) * (fp - fret - del) * (fp - fret - del) -
                       del * (fp - fptt) * (fp - fptt);
      if (t < 0.0 && glm::dot(xit, xit) > 0.0) {
        line_minimize(F, p, xit, fret, line_tol);
        xi[ibig] = xi[2];
        xi[2] = xit;
      }
    }
  }
  res.x = p;
  res.f = fret;
  return res;
}

}  // namespace detail

namespace {
using glm::dvec2;
using glm::dvec3;
constexpr double kPi = std::numbers::pi;

std::string num(double x) {
  std::ostringstream os;
  os.precision(9);
  os << x;
  return os.str();
}
std::string vstr(const dvec3& v) { return "(" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + ")"; }

double sphere_volume(double r) { return 4.0 / 3.0 * kPi * r * r * r; }

void check_trimesh(const TriMesh& m, const std::string& who) {
  if (m.positions.empty() || m.triangles.empty())
    throw std::invalid_argument(who + ": the mesh is empty (" + std::to_string(m.positions.size()) + " vertices, " +
                                std::to_string(m.triangles.size()) + " triangles)");
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const glm::vec3& p = m.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw std::invalid_argument(who + ": vertex " + std::to_string(i) + " has a non-finite coordinate " + vstr(p));
  }
  for (size_t t = 0; t < m.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (m.triangles[t][k] >= m.positions.size())
        throw std::invalid_argument(who + ": triangle " + std::to_string(t) + " references vertex " +
                                    std::to_string(m.triangles[t][k]) + " but the mesh has " +
                                    std::to_string(m.positions.size()) + " vertices");
}

// Merges vertices with bit-identical positions (glTF splits vertices along normal/uv seams) and
// drops triangles that collapse; adjacency and the closedness check need the welded mesh.
TriMesh weld(const TriMesh& in) {
  struct Key {
    std::uint32_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      return (static_cast<size_t>(k.x) * 73856093u) ^ (static_cast<size_t>(k.y) * 19349663u) ^
             (static_cast<size_t>(k.z) * 83492791u);
    }
  };
  auto bits = [](float f) {
    f += 0.0f;  // -0 and +0 weld
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
  };
  TriMesh out;
  std::unordered_map<Key, std::uint32_t, Hash> index;
  std::vector<std::uint32_t> remap(in.positions.size());
  for (size_t i = 0; i < in.positions.size(); ++i) {
    const glm::vec3& p = in.positions[i];
    Key k{bits(p.x), bits(p.y), bits(p.z)};
    auto [it, added] = index.emplace(k, static_cast<std::uint32_t>(out.positions.size()));
    if (added) out.positions.push_back(p);
    remap[i] = it->second;
  }
  for (const glm::uvec3& t : in.triangles) {
    glm::uvec3 w(remap[t.x], remap[t.y], remap[t.z]);
    if (w.x == w.y || w.y == w.z || w.z == w.x) continue;
    out.triangles.push_back(w);
  }
  return out;
}

// Every directed edge must be matched by its reverse: a closed, consistently oriented surface,
// without which "inside" and V(S - T) mean nothing.
void check_closed(const TriMesh& m, const std::string& who) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> count;
  for (const glm::uvec3& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      if (a < b) ++count[{a, b}];
      else --count[{b, a}];
    }
  size_t open = 0;
  std::pair<std::uint32_t, std::uint32_t> first{0, 0};
  int first_count = 0;
  for (const auto& [e, c] : count)
    if (c != 0) {
      if (open == 0) {
        first = e;
        first_count = c;
      }
      ++open;
    }
  if (open > 0)
    throw std::invalid_argument(who + ": the mesh is not closed: " + std::to_string(open) +
                                " edges are not matched by an opposite edge, e.g. between vertices " +
                                std::to_string(first.first) + " " + vstr(m.positions[first.first]) + " and " +
                                std::to_string(first.second) + " " + vstr(m.positions[first.second]) +
                                " (unmatched count " + std::to_string(first_count) + ")");
}

// ---------------------------------------------------------------------------------------------
// Triangles in double precision and a bounding volume hierarchy over them.
struct TriD {
  dvec3 p[3];
  dvec3 n;      // unit normal of the winding (outward for a positive-volume mesh)
  dvec3 u, v;   // in-plane frame with u x v = n
  double area = 0.0;
  dvec3 lo, hi;
};

struct BvhNode {
  dvec3 lo, hi;
  int left = -1, right = -1;  // children, or -1 for a leaf
  int first = 0, count = 0;   // range in Bvh::order for leaves
};

class Bvh {
 public:
  void build(const std::vector<TriD>& tris) {
    order_.resize(tris.size());
    for (size_t i = 0; i < tris.size(); ++i) order_[i] = static_cast<int>(i);
    nodes_.clear();
    nodes_.reserve(2 * tris.size() + 1);
    if (!tris.empty()) build_node(tris, 0, static_cast<int>(tris.size()));
  }
  // Calls f(triangle index) for every triangle whose bounding box meets the ball.
  template <class F>
  void ball(const dvec3& c, double r, F&& f) const {
    if (nodes_.empty()) return;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    const double r2 = r * r;
    while (top > 0) {
      const BvhNode& nd = nodes_[stack[--top]];
      const dvec3 q = glm::clamp(c, nd.lo, nd.hi) - c;
      if (glm::dot(q, q) > r2) continue;
      if (nd.left < 0) {
        for (int i = nd.first; i < nd.first + nd.count; ++i) f(order_[i]);
      } else {
        stack[top++] = nd.left;
        stack[top++] = nd.right;
      }
    }
  }
  // Calls f(triangle index) for every triangle whose bounding box the ray o + t d (t >= 0) meets.
  template <class F>
  void ray(const dvec3& o, const dvec3& d, F&& f) const {
    if (nodes_.empty()) return;
    const dvec3 inv(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BvhNode& nd = nodes_[stack[--top]];
      const dvec3 t0 = (nd.lo - o) * inv, t1 = (nd.hi - o) * inv;
      const dvec3 tmin = glm::min(t0, t1), tmax = glm::max(t0, t1);
      const double enter = std::max({tmin.x, tmin.y, tmin.z, 0.0});
      const double leave = std::min({tmax.x, tmax.y, tmax.z});
      if (enter > leave * (1.0 + 1e-12) + 1e-300) continue;
      if (nd.left < 0) {
        for (int i = nd.first; i < nd.first + nd.count; ++i) f(order_[i]);
      } else {
        stack[top++] = nd.left;
        stack[top++] = nd.right;
      }
    }
  }

 private:
  int build_node(const std::vector<TriD>& tris, int first, int count) {
    const int id = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    dvec3 clo = lo, chi = hi;
    for (int i = first; i < first + count; ++i) {
      const TriD& t = tris[order_[i]];
      lo = glm::min(lo, t.lo);
      hi = glm::max(hi, t.hi);
      const dvec3 c = 0.5 * (t.lo + t.hi);
      clo = glm::min(clo, c);
      chi = glm::max(chi, c);
    }
    // Slightly inflated so that queries on the boundary are not lost to rounding.
    const dvec3 pad = 1e-12 * (glm::abs(lo) + glm::abs(hi)) + 1e-300;
    nodes_[id].lo = lo - pad;
    nodes_[id].hi = hi + pad;
    if (count <= 4) {
      nodes_[id].first = first;
      nodes_[id].count = count;
      return id;
    }
    const dvec3 ext = chi - clo;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const int mid = first + count / 2;
    std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + first + count, [&](int a, int b) {
      return tris[a].lo[axis] + tris[a].hi[axis] < tris[b].lo[axis] + tris[b].hi[axis];
    });
    const int left = build_node(tris, first, mid - first);
    const int right = build_node(tris, mid, first + count - mid);
    nodes_[id].left = left;
    nodes_[id].right = right;
    return id;
  }

  std::vector<BvhNode> nodes_;
  std::vector<int> order_;
};

double cross2(const dvec2& a, const dvec2& b) { return a.x * b.y - a.y * b.x; }

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5).
dvec3 closest_on_triangle(const dvec3& p, const dvec3& a, const dvec3& b, const dvec3& c) {
  const dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// The part of the ball B(c, r) in the cone from c over triangle t, minus the full-sphere sector of
// that cone: (h A_in - sgn(h) r^3 Omega_in) / 3, where h is the signed distance from c to t's plane
// (positive when c is behind t), A_in the oriented area of t inside the ball and Omega_in the
// oriented solid angle of that part seen from c. Summed over the triangles meeting the ball and
// added to w(c) V(S) it gives V(S ∩ T) exactly: the signed cones from c over the triangles add up
// to the indicator of T (Wang et al. 2006 section 4 sum the same signed cone volumes), and a cone
// over a triangle entirely outside the ball holds exactly its full-sphere sector r^3 Omega / 3.
double triangle_term(const TriD& t, const dvec3& c, double r) {
  const double h = glm::dot(t.n, t.p[0] - c);
  const double d = std::abs(h);
  if (d >= r) return 0.0;
  const double r2 = r * r;
  const dvec3 a = t.p[0] - c, b = t.p[1] - c, e = t.p[2] - c;
  const double la2 = glm::dot(a, a), lb2 = glm::dot(b, b), le2 = glm::dot(e, e);
  if (la2 <= r2 && lb2 <= r2 && le2 <= r2) {
    // Whole triangle in the ball: Van Oosterom-Strackee solid angle, signed like h.
    const double la = std::sqrt(la2), lb = std::sqrt(lb2), le = std::sqrt(le2);
    const double det = glm::dot(a, glm::cross(b, e));
    const double den = la * lb * le + glm::dot(a, b) * le + glm::dot(a, e) * lb + glm::dot(b, e) * la;
    const double omega = 2.0 * std::atan2(det, den);
    return (h * t.area - r2 * r * omega) / 3.0;
  }
  const double rho2 = r2 - h * h;
  const dvec3 foot = c + h * t.n;
  dvec2 q[3];
  for (int k = 0; k < 3; ++k) {
    const dvec3 w = t.p[k] - foot;
    q[k] = dvec2(glm::dot(w, t.u), glm::dot(w, t.v));
  }
  const double cap = 1.0 - d / r;  // solid angle per radian of a sector of the disk (cone cap)
  double area_in = 0.0, omega_in = 0.0;
  auto sector = [&](const dvec2& A, const dvec2& B) {
    const double phi = std::atan2(cross2(A, B), glm::dot(A, B));
    area_in += 0.5 * rho2 * phi;
    omega_in += phi * cap;
  };
  auto triangle = [&](const dvec2& A, const dvec2& B) {
    const double cr = cross2(A, B);
    area_in += 0.5 * cr;
    const double LA = std::sqrt(glm::dot(A, A) + d * d), LB = std::sqrt(glm::dot(B, B) + d * d);
    const double om = 2.0 * std::atan2(std::abs(cr), LA * LB + d * (LA + LB) + glm::dot(A, B) + d * d);
    omega_in += std::copysign(om, cr);
  };
  // Fan from the foot of the perpendicular (the disk centre): each edge's piece is a triangle where
  // the edge runs inside the disk and a circular sector where it runs outside.
  for (int k = 0; k < 3; ++k) {
    const dvec2 P = q[k], Q = q[(k + 1) % 3], D = Q - P;
    const double qa = glm::dot(D, D);
    if (qa <= 0.0) continue;
    const double qb = glm::dot(P, D), qc = glm::dot(P, P) - rho2;
    const double disc = qb * qb - qa * qc;
    double s0 = 1.0, s1 = 0.0;
    if (disc > 0.0) {
      const double sq = std::sqrt(disc);
      s0 = std::max((-qb - sq) / qa, 0.0);
      s1 = std::min((-qb + sq) / qa, 1.0);
    }
    if (s0 >= s1) {
      sector(P, Q);
    } else {
      const dvec2 X0 = P + s0 * D, X1 = P + s1 * D;
      if (s0 > 0.0) sector(P, X0);
      triangle(X0, X1);
      if (s1 < 1.0) sector(X1, Q);
    }
  }
  return (h * area_in - (h >= 0.0 ? 1.0 : -1.0) * r2 * r * omega_in) / 3.0;
}

// A closed triangle mesh ready for inside tests and ball-intersection volumes.
class Solid {
 public:
  Solid(const TriMesh& mesh, const std::string& who) {
    check_trimesh(mesh, who);
    welded_ = weld(mesh);
    if (welded_.triangles.empty()) throw std::invalid_argument(who + ": every triangle of the mesh is degenerate");
    check_closed(welded_, who);
    lo_ = dvec3(std::numeric_limits<double>::infinity());
    hi_ = -lo_;
    for (const glm::vec3& p : welded_.positions) {
      lo_ = glm::min(lo_, dvec3(p));
      hi_ = glm::max(hi_, dvec3(p));
    }
    scale_ = glm::length(hi_ - lo_);
    if (!(scale_ > 0.0)) throw std::invalid_argument(who + ": the mesh has zero extent");
    eps_ = 1e-11 * scale_;
    delta_ = 1e-6 * scale_;
    const dvec3 origin = 0.5 * (lo_ + hi_);
    double vol = 0.0;
    for (const glm::uvec3& tri : welded_.triangles) {
      TriD t;
      for (int k = 0; k < 3; ++k) t.p[k] = dvec3(welded_.positions[tri[k]]);
      const dvec3 n2 = glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]);
      const double len = glm::length(n2);
      vol += glm::dot(t.p[0] - origin, glm::cross(t.p[1] - origin, t.p[2] - origin)) / 6.0;
      if (!(len > 1e-15 * scale_ * scale_)) continue;  // zero area: no volume, never crossed
      t.n = n2 / len;
      t.area = 0.5 * len;
      t.u = glm::normalize(t.p[1] - t.p[0]);
      t.v = glm::cross(t.n, t.u);
      t.lo = glm::min(t.p[0], glm::min(t.p[1], t.p[2]));
      t.hi = glm::max(t.p[0], glm::max(t.p[1], t.p[2]));
      tris_.push_back(t);
    }
    volume_ = vol;
    if (!(volume_ > 0.0))
      throw std::invalid_argument(who + ": the mesh encloses a non-positive volume (" + num(volume_) +
                                  "): inverted winding or not a solid");
    bvh_.build(tris_);
    // Overlapping or inverted parts show as winding numbers other than 0 and 1; a coarse grid
    // catches all but thin ones (the fit checks its own finer grid again).
    const dvec3 ext = hi_ - lo_;
    const double cell = std::max({ext.x, ext.y, ext.z}) / 16.0;
    const glm::ivec3 n(static_cast<int>(ext.x / cell) + 1, static_cast<int>(ext.y / cell) + 1, static_cast<int>(ext.z / cell) + 1);
    std::vector<int> bad(n.z, -1);
    tbb::parallel_for(0, n.z, [&](int k) {
      for (int j = 0; j < n.y && bad[k] < 0; ++j)
        for (int i = 0; i < n.x; ++i) {
          const int w = winding(lo_ + cell * dvec3(i + 0.5, j + 0.5, k + 0.5));
          if (w < 0 || w > 1) {
            bad[k] = j * n.x + i;
            break;
          }
        }
    });
    for (int k = 0; k < n.z; ++k)
      if (bad[k] >= 0) check_winding(lo_ + cell * dvec3(bad[k] % n.x + 0.5, bad[k] / n.x + 0.5, k + 0.5), who);
  }

  const TriMesh& welded() const { return welded_; }
  const std::vector<TriD>& tris() const { return tris_; }
  const Bvh& bvh() const { return bvh_; }
  double volume() const { return volume_; }
  double scale() const { return scale_; }
  dvec3 lo() const { return lo_; }
  dvec3 hi() const { return hi_; }

  // Winding number by signed ray crossings (+1 leaving through a face, -1 entering) along a few
  // fixed directions; a direction whose ray passes within rounding of an edge, a vertex or its own
  // origin is abandoned for the next. 1 inside, 0 outside for a proper closed surface.
  int winding(const dvec3& p) const {
    static const dvec3 kDirs[] = {glm::normalize(dvec3(0.5427, 0.6631, 0.5155)),
                                  glm::normalize(dvec3(-0.6173, 0.4211, -0.6647)),
                                  glm::normalize(dvec3(0.3119, -0.7717, 0.5543)),
                                  glm::normalize(dvec3(-0.2311, -0.3877, -0.8923)),
                                  glm::normalize(dvec3(0.8812, -0.1533, -0.4471))};
    int fallback = 0;
    bool have_fallback = false;
    for (const dvec3& d : kDirs) {
      int w = 0;
      bool ambiguous = false;
      bvh_.ray(p, d, [&](int i) {
        if (ambiguous) return;
        const int hit = ray_hit(tris_[i], p, d);
        if (hit < 0) ambiguous = true;
        else if (hit > 0) w += glm::dot(tris_[i].n, d) > 0.0 ? 1 : -1;
      });
      if (!ambiguous) return w;
      if (!have_fallback) {
        fallback = w;
        have_fallback = true;
      }
    }
    return fallback;
  }
  bool inside(const dvec3& p) const { return winding(p) > 0; }

  // The triangle sums integrate the winding number, so V(S ∩ T) is the solid's volume only where it
  // is 0 or 1: overlapping closed parts (a union of capsules) or inverted parts must be merged first.
  void check_winding(const dvec3& p, const std::string& who) const {
    const int w = winding(p);
    if (w < 0 || w > 1)
      throw std::invalid_argument(who + ": the mesh " + (w > 1 ? "overlaps itself" : "has inverted parts") +
                                  " (winding number " + std::to_string(w) + " at " + vstr(p) +
                                  "); outside volumes need one closed surface: merge the overlapping parts (a mesh union) first");
  }

  // V(S ∩ T) for the ball B(c, r): w(c) V(S) plus the triangle terms of the triangles meeting the ball.
  double intersection(const dvec3& c, double r) const {
    if (!(r > 0.0)) return 0.0;
    thread_local std::vector<int> near;
    near.clear();
    bvh_.ball(c, r + delta_, [&](int i) { near.push_back(i); });
    // Within delta_ of the surface the triangle terms lose digits (the foot of the perpendicular sits
    // within rounding of an edge) and w(c) is a matter of rounding; V(S ∩ T) is smooth in c there,
    // so take the central difference across the surface: error O(delta^2).
    dvec3 m(0.0), first(0.0);
    bool close = false;
    for (int i : near) {
      const TriD& t = tris_[i];
      if (std::abs(glm::dot(t.n, t.p[0] - c)) >= delta_) continue;
      const dvec3 q = closest_on_triangle(c, t.p[0], t.p[1], t.p[2]);
      if (glm::dot(q - c, q - c) >= delta_ * delta_) continue;
      if (!close) first = t.n;
      close = true;
      m += t.n;
    }
    if (!close) return intersection_at(c, r, near);
    m = glm::length(m) > 1e-3 ? glm::normalize(m) : first;
    return 0.5 * (intersection_at(c + delta_ * m, r, near) + intersection_at(c - delta_ * m, r, near));
  }

  double outside(const dvec3& c, double r) const {
    if (!(r > 0.0)) return 0.0;
    const double vs = sphere_volume(r);
    return std::clamp(vs - intersection(c, r), 0.0, vs);
  }

 private:
  // V(S ∩ T) from candidate triangles `near` (a superset of those meeting the ball).
  double intersection_at(dvec3 c, double r, const std::vector<int>& near) const {
    // Safety net for a centre still within rounding of the surface: step inwards by a few eps.
    for (int attempt = 0; attempt < 4; ++attempt) {
      bool moved = false;
      for (int i : near) {
        const TriD& t = tris_[i];
        if (std::abs(glm::dot(t.n, t.p[0] - c)) >= eps_) continue;
        const dvec3 q = closest_on_triangle(c, t.p[0], t.p[1], t.p[2]);
        if (glm::dot(q - c, q - c) < eps_ * eps_) {
          c -= 4.0 * eps_ * t.n;
          moved = true;
          break;
        }
      }
      if (!moved) break;
    }
    double v = inside(c) ? sphere_volume(r) : 0.0;
    for (int i : near) v += triangle_term(tris_[i], c, r);
    return v;
  }

  // Moller-Trumbore; 1 hit, 0 miss, -1 undecidable within rounding.
  int ray_hit(const TriD& t, const dvec3& o, const dvec3& d) const {
    constexpr double kBary = 1e-9;
    const dvec3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0];
    const dvec3 pv = glm::cross(d, e2);
    const double det = glm::dot(e1, pv);
    if (std::abs(det) < 1e-12 * 2.0 * t.area) {
      // Grazing: decidable only if the origin is clearly off the plane (then the ray cannot cross).
      return std::abs(glm::dot(t.n, o - t.p[0])) > eps_ ? 0 : -1;
    }
    const double inv = 1.0 / det;
    const dvec3 tv = o - t.p[0];
    const double u = glm::dot(tv, pv) * inv;
    if (u < -kBary || u > 1.0 + kBary) return 0;
    const dvec3 qv = glm::cross(tv, e1);
    const double v = glm::dot(d, qv) * inv;
    if (v < -kBary || u + v > 1.0 + kBary) return 0;
    const double tt = glm::dot(e2, qv) * inv;
    if (tt < -eps_) return 0;
    if (u < kBary || v < kBary || u + v > 1.0 - kBary || tt < eps_) return -1;
    return 1;
  }

  TriMesh welded_;
  std::vector<TriD> tris_;
  Bvh bvh_;
  dvec3 lo_, hi_;
  double scale_ = 0.0, eps_ = 0.0, delta_ = 0.0, volume_ = 0.0;
};

// ---------------------------------------------------------------------------------------------
// Sample points and their neighbourhood graph (paper 004 6.2: triangle midpoints and the corners of
// a voxelisation grid inside the mesh; neighbours along the mesh and the grid).
struct Samples {
  std::vector<dvec3> p;
  std::vector<int> adj_start, adj;  // CSR
  size_t surface = 0;               // p[0, surface) lie on the surface
};

void validate_options(const FitOptions& opt) {
  auto bad = [](const std::string& field, const std::string& value, const std::string& why) {
    throw std::invalid_argument("sphere fit option " + field + " = " + value + ": " + why);
  };
  if (opt.spheres < 1 || opt.spheres > 100000) bad("spheres", std::to_string(opt.spheres), "must be in [1, 100000]");
  if (opt.surface_points < 0 || opt.surface_points > 10000000)
    bad("surface_points", std::to_string(opt.surface_points), "must be in [0, 10000000] (0: triangle midpoints)");
  if (opt.grid_resolution < 1 || opt.grid_resolution > 512)
    bad("grid_resolution", std::to_string(opt.grid_resolution), "must be in [1, 512]");
  if (opt.max_iterations < 1 || opt.max_iterations > 100000)
    bad("max_iterations", std::to_string(opt.max_iterations), "must be in [1, 100000]");
  if (opt.teleport_after_stall < 1) bad("teleport_after_stall", std::to_string(opt.teleport_after_stall), "must be >= 1");
  if (!(opt.stall_tolerance >= 0.0 && opt.stall_tolerance < 1.0))
    bad("stall_tolerance", num(opt.stall_tolerance), "must be in [0, 1)");
}

Samples make_samples(const Solid& solid, const FitOptions& opt, const std::string& who) {
  const TriMesh& m = solid.welded();
  Samples s;
  std::vector<std::pair<int, int>> edges;
  for (const glm::vec3& p : m.positions) s.p.emplace_back(p);
  for (const glm::uvec3& t : m.triangles)
    for (int k = 0; k < 3; ++k) edges.emplace_back(t[k], t[(k + 1) % 3]);
  if (opt.surface_points == 0) {
    // Triangle midpoints, linked to their corners and to the midpoints across each edge.
    std::unordered_map<std::uint64_t, int> edge_tri;
    for (size_t ti = 0; ti < m.triangles.size(); ++ti) {
      const glm::uvec3& t = m.triangles[ti];
      const int mid = static_cast<int>(s.p.size());
      s.p.push_back((dvec3(m.positions[t.x]) + dvec3(m.positions[t.y]) + dvec3(m.positions[t.z])) / 3.0);
      for (int k = 0; k < 3; ++k) {
        edges.emplace_back(mid, static_cast<int>(t[k]));
        const std::uint64_t a = std::min(t[k], t[(k + 1) % 3]), b = std::max(t[k], t[(k + 1) % 3]);
        auto [it, added] = edge_tri.emplace((a << 32) | b, mid);
        if (!added) edges.emplace_back(mid, it->second);
      }
    }
  } else {
    // Area-weighted random samples, linked to the corners of their triangle.
    std::vector<double> cdf;
    double total = 0.0;
    for (const glm::uvec3& t : m.triangles) {
      total += 0.5 * glm::length(glm::cross(dvec3(m.positions[t.y]) - dvec3(m.positions[t.x]),
                                            dvec3(m.positions[t.z]) - dvec3(m.positions[t.x])));
      cdf.push_back(total);
    }
    std::mt19937_64 rng(opt.seed * 0x9E3779B97F4A7C15ull + 17);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int i = 0; i < opt.surface_points; ++i) {
      const size_t ti = std::min<size_t>(std::lower_bound(cdf.begin(), cdf.end(), U(rng) * total) - cdf.begin(),
                                         m.triangles.size() - 1);
      double a = U(rng), b = U(rng);
      if (a + b > 1.0) {
        a = 1.0 - a;
        b = 1.0 - b;
      }
      const glm::uvec3& t = m.triangles[ti];
      const dvec3 p0(m.positions[t.x]), p1(m.positions[t.y]), p2(m.positions[t.z]);
      const int id = static_cast<int>(s.p.size());
      s.p.push_back(p0 + a * (p1 - p0) + b * (p2 - p0));
      for (int k = 0; k < 3; ++k) edges.emplace_back(id, static_cast<int>(t[k]));
    }
  }
  s.surface = s.p.size();

  // Interior: grid corners inside the mesh, linked along the grid and to the surface points of
  // their cells.
  const dvec3 lo = solid.lo(), ext = solid.hi() - solid.lo();
  const double cell = std::max({ext.x, ext.y, ext.z}) / opt.grid_resolution;
  const glm::ivec3 n(static_cast<int>(std::floor(ext.x / cell)) + 2, static_cast<int>(std::floor(ext.y / cell)) + 2,
                     static_cast<int>(std::floor(ext.z / cell)) + 2);
  const size_t ncorners = static_cast<size_t>(n.x) * n.y * n.z;
  if (ncorners > 50'000'000) throw std::invalid_argument("sphere fit: voxel grid too large");
  auto corner = [&](int i, int j, int k) { return lo + cell * dvec3(i, j, k); };
  std::vector<std::uint8_t> in(ncorners, 0);
  std::vector<int> wind(ncorners, 0);
  tbb::parallel_for(0, n.z, [&](int k) {
    for (int j = 0; j < n.y; ++j)
      for (int i = 0; i < n.x; ++i) wind[(static_cast<size_t>(k) * n.y + j) * n.x + i] = solid.winding(corner(i, j, k));
  });
  for (size_t c = 0; c < ncorners; ++c) {
    if (wind[c] < 0 || wind[c] > 1) {
      const int i = static_cast<int>(c % n.x), j = static_cast<int>((c / n.x) % n.y), k = static_cast<int>(c / (static_cast<size_t>(n.x) * n.y));
      solid.check_winding(corner(i, j, k), who);
    }
    in[c] = wind[c] > 0;
  }
  std::vector<int> id(ncorners, -1);
  for (int k = 0; k < n.z; ++k)
    for (int j = 0; j < n.y; ++j)
      for (int i = 0; i < n.x; ++i) {
        const size_t c = (static_cast<size_t>(k) * n.y + j) * n.x + i;
        if (!in[c]) continue;
        id[c] = static_cast<int>(s.p.size());
        s.p.push_back(corner(i, j, k));
        if (i > 0 && id[c - 1] >= 0) edges.emplace_back(id[c], id[c - 1]);
        if (j > 0 && id[c - n.x] >= 0) edges.emplace_back(id[c], id[c - n.x]);
        if (k > 0 && id[c - static_cast<size_t>(n.x) * n.y] >= 0)
          edges.emplace_back(id[c], id[c - static_cast<size_t>(n.x) * n.y]);
      }
  for (size_t si = 0; si < s.surface; ++si) {
    const dvec3 g = (s.p[si] - lo) / cell;
    const int i0 = std::clamp(static_cast<int>(std::floor(g.x)), 0, n.x - 2);
    const int j0 = std::clamp(static_cast<int>(std::floor(g.y)), 0, n.y - 2);
    const int k0 = std::clamp(static_cast<int>(std::floor(g.z)), 0, n.z - 2);
    for (int dk = 0; dk < 2; ++dk)
      for (int dj = 0; dj < 2; ++dj)
        for (int di = 0; di < 2; ++di) {
          const int c = id[(static_cast<size_t>(k0 + dk) * n.y + j0 + dj) * n.x + i0 + di];
          if (c >= 0) edges.emplace_back(static_cast<int>(si), c);
        }
  }
  // CSR, both directions, without duplicates.
  std::vector<std::pair<int, int>> both;
  both.reserve(2 * edges.size());
  for (auto [a, b] : edges) {
    both.emplace_back(a, b);
    both.emplace_back(b, a);
  }
  std::sort(both.begin(), both.end());
  both.erase(std::unique(both.begin(), both.end()), both.end());
  s.adj_start.assign(s.p.size() + 1, 0);
  for (auto [a, b] : both) ++s.adj_start[a + 1];
  for (size_t i = 0; i < s.p.size(); ++i) s.adj_start[i + 1] += s.adj_start[i];
  s.adj.resize(both.size());
  for (size_t i = 0; i < both.size(); ++i) s.adj[i] = both[i].second;  // sorted by a: already in place
  return s;
}

// ---------------------------------------------------------------------------------------------
// The variational fit.

// f(r) = V(B(c, r) - T) for a fixed centre, tabulated on demand at a fixed radius step and
// interpolated linearly: the clustering compares thousands of radius extensions per iteration with
// the centres held fixed (paper 004 6.2: "error from adding a point is measured by extending the
// cluster sphere's radius"). The spheres that are kept are evaluated exactly.
class RadiusTable {
 public:
  void reset(const dvec3& c, double dr) {
    c_ = c;
    dr_ = dr;
    f_.assign(1, 0.0);
  }
  void extend_to(double r, const Solid& solid) {
    const size_t need = static_cast<size_t>(std::ceil(r / dr_)) + 2;
    while (f_.size() < need) f_.push_back(std::max(f_.back(), solid.outside(c_, dr_ * static_cast<double>(f_.size()))));
  }
  double at(double r, const Solid& solid) {
    extend_to(r, solid);
    const double x = r / dr_;
    const size_t k = static_cast<size_t>(x);
    return f_[k] + (x - static_cast<double>(k)) * (f_[k + 1] - f_[k]);
  }

 private:
  dvec3 c_{0.0};
  double dr_ = 1.0;
  std::vector<double> f_;
};

struct State {
  std::vector<dvec3> centre;
  std::vector<double> radius;
  std::vector<double> outside;  // V(S_i - T)
  std::vector<int> label;       // cluster of each point
  double E = std::numeric_limits<double>::infinity();  // sum V(S_i - T) / V(T)
};

class Fitter {
 public:
  Fitter(const Solid& solid, const Samples& samples, int spheres)
      : solid_(solid), s_(samples), tables_(spheres), dr_(solid.scale() / 256.0) {}

  // Flood-fill clustering from the current centres (radii restart at 0). A point is taken from a
  // priority queue ordered by the error increase it causes to a neighbouring cluster (ties: nearest
  // centre), i.e. the flood assigns each point to the neighbouring cluster of minimal error increase.
  void cluster(State& st) {
    const int K = static_cast<int>(st.centre.size());
    const size_t N = s_.p.size();
    st.label.assign(N, -1);
    st.radius.assign(K, 0.0);
    // Prefill the tables to about the radius of the previous iteration, in parallel.
    std::vector<double> hint(K, 0.0);
    for (int i = 0; i < K; ++i) hint[i] = i < static_cast<int>(prev_radius_.size()) ? 1.2 * prev_radius_[i] : 0.0;
    tbb::parallel_for(0, K, [&](int i) {
      tables_[i].reset(st.centre[i], dr_);
      tables_[i].extend_to(hint[i], solid_);
    });
    struct Cand {
      double key, dist;
      int point, cluster;
      bool operator>(const Cand& o) const {
        if (key != o.key) return key > o.key;
        if (dist != o.dist) return dist > o.dist;
        if (point != o.point) return point > o.point;
        return cluster > o.cluster;
      }
    };
    std::priority_queue<Cand, std::vector<Cand>, std::greater<Cand>> pq;
    auto increase = [&](int q, int i, double& dist) {
      dist = glm::length(s_.p[q] - st.centre[i]);
      if (dist <= st.radius[i]) return 0.0;
      return tables_[i].at(dist, solid_) - tables_[i].at(st.radius[i], solid_);
    };
    auto assign = [&](int q, int i, double dist) {
      st.label[q] = i;
      st.radius[i] = std::max(st.radius[i], dist);
      for (int a = s_.adj_start[q]; a < s_.adj_start[q + 1]; ++a) {
        const int nb = s_.adj[a];
        if (st.label[nb] >= 0) continue;
        double d = 0.0;
        const double key = increase(nb, i, d);
        pq.push({key, d, nb, i});
      }
    };
    // Seeds: the point nearest each centre.
    for (int i = 0; i < K; ++i) {
      int best = -1;
      double bd = std::numeric_limits<double>::infinity();
      for (size_t q = 0; q < N; ++q) {
        if (st.label[q] >= 0) continue;
        const dvec3 dd = s_.p[q] - st.centre[i];
        const double d2 = glm::dot(dd, dd);
        if (d2 < bd) {
          bd = d2;
          best = static_cast<int>(q);
        }
      }
      st.label[best] = i;
      st.radius[i] = std::sqrt(bd);
    }
    for (size_t q = 0; q < N; ++q)
      if (st.label[q] >= 0) assign(static_cast<int>(q), st.label[q], st.radius[st.label[q]]);
    size_t next_unassigned = 0;
    for (;;) {
      while (!pq.empty()) {
        const Cand c = pq.top();
        pq.pop();
        if (st.label[c.point] >= 0) continue;
        double d = 0.0;
        const double key = increase(c.point, c.cluster, d);
        if (key != c.key) {  // the cluster grew since: its cost only went down
          pq.push({key, d, c.point, c.cluster});
          continue;
        }
        assign(c.point, c.cluster, d);
      }
      // Points the flood could not reach (a part of the mesh without any seed): the cluster of
      // least error increase over all, then flood on from there.
      while (next_unassigned < N && st.label[next_unassigned] >= 0) ++next_unassigned;
      if (next_unassigned == N) break;
      const int q = static_cast<int>(next_unassigned);
      int best = 0;
      double bk = std::numeric_limits<double>::infinity(), bdist = 0.0;
      for (int i = 0; i < K; ++i) {
        double d = 0.0;
        const double key = increase(q, i, d);
        if (key < bk || (key == bk && d < bdist)) {
          bk = key;
          bdist = d;
          best = i;
        }
      }
      assign(q, best, bdist);
    }
    prev_radius_ = st.radius;
    members_of(st);
    st.outside.assign(K, 0.0);
    tbb::parallel_for(0, K, [&](int i) { st.outside[i] = solid_.outside(st.centre[i], st.radius[i]); });
    st.E = sum(st.outside) / solid_.volume();
  }

  // Per-cluster sphere update: the centre minimising V(S - T) with r = max distance to the
  // cluster's points (so the bound holds by construction), by Powell's method.
  void update(State& st) {
    const int K = static_cast<int>(st.centre.size());
    members_of(st);
    tbb::parallel_for(0, K, [&](int i) {
      const int* mb = members_.data() + member_start_[i];
      const int count = member_start_[i + 1] - member_start_[i];
      auto radius_at = [&](const dvec3& c) {
        double r2 = 0.0;
        for (int k = 0; k < count; ++k) {
          const dvec3 d = s_.p[mb[k]] - c;
          r2 = std::max(r2, glm::dot(d, d));
        }
        return std::sqrt(r2);
      };
      auto objective = [&](const dvec3& c) { return solid_.outside(c, radius_at(c)); };
      const double step = std::max(0.25 * st.radius[i], dr_);
      const detail::PowellResult res =
          detail::powell_minimize(objective, st.centre[i], step, kPowellFtol, kPowellLineTol, kPowellSweeps, 400);
      st.centre[i] = res.x;
      st.radius[i] = radius_at(res.x);
      st.outside[i] = res.f;
    });
    st.E = sum(st.outside) / solid_.volume();
  }

  // Cluster teleportation (Cohen-Steiner et al. 2004 via paper 004 6.2): the cluster of maximal
  // error is split at its farthest-apart pair of points and the cluster of maximal overlap (volume
  // shared with the other spheres, here the sum of pairwise lens volumes, over its own volume) is
  // removed; attempt k removes the k-th most overlapping instead. Returns false when there is no
  // such cluster or the worst cluster cannot be split.
  bool teleport(State& st, int attempt) {
    const int K = static_cast<int>(st.centre.size());
    if (K < 2) return false;
    members_of(st);
    const int worst = static_cast<int>(std::max_element(st.outside.begin(), st.outside.end()) - st.outside.begin());
    const int* mb = members_.data() + member_start_[worst];
    const int count = member_start_[worst + 1] - member_start_[worst];
    if (count < 2) return false;
    int pa = mb[0], pb = mb[0];
    double best = -1.0;
    for (int a = 0; a < count; ++a)
      for (int b = a + 1; b < count; ++b) {
        const dvec3 d = s_.p[mb[a]] - s_.p[mb[b]];
        const double d2 = glm::dot(d, d);
        if (d2 > best) {
          best = d2;
          pa = mb[a];
          pb = mb[b];
        }
      }
    std::vector<std::pair<double, int>> overlap;
    for (int j = 0; j < K; ++j) {
      if (j == worst) continue;
      const double vj = sphere_volume(st.radius[j]);
      double shared = 0.0;
      for (int k = 0; k < K; ++k)
        if (k != j) shared += lens_volume(st.centre[j], st.radius[j], st.centre[k], st.radius[k]);
      overlap.emplace_back(vj > 0.0 ? -shared / vj : -std::numeric_limits<double>::infinity(), j);
    }
    if (attempt >= static_cast<int>(overlap.size())) return false;
    std::nth_element(overlap.begin(), overlap.begin() + attempt, overlap.end());
    const int victim = overlap[attempt].second;
    st.centre[worst] = s_.p[pa];
    st.centre[victim] = s_.p[pb];
    return true;
  }

  void members_of(const State& st) {
    const int K = static_cast<int>(st.centre.size());
    member_start_.assign(K + 1, 0);
    for (int l : st.label) ++member_start_[l + 1];
    for (int i = 0; i < K; ++i) member_start_[i + 1] += member_start_[i];
    members_.resize(st.label.size());
    std::vector<int> fill(member_start_.begin(), member_start_.end() - 1);
    for (size_t q = 0; q < st.label.size(); ++q) members_[fill[st.label[q]]++] = static_cast<int>(q);
  }

  static double lens_volume(const dvec3& c1, double r1, const dvec3& c2, double r2) {
    const double d = glm::length(c1 - c2);
    if (d >= r1 + r2) return 0.0;
    if (d <= std::abs(r1 - r2)) return sphere_volume(std::min(r1, r2));
    return kPi * (r1 + r2 - d) * (r1 + r2 - d) * (d * d + 2.0 * d * r2 - 3.0 * r2 * r2 + 2.0 * d * r1 + 6.0 * r1 * r2 - 3.0 * r1 * r1) /
           (12.0 * d);
  }
  static double sum(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return s;
  }

  // Powell settings for the centre update: a few sweeps per iteration suffice because the next
  // iteration starts from the result (measured: more sweeps lower E by < 1% on the bunny at 3x cost).
  static constexpr double kPowellFtol = 1e-3;
  static constexpr double kPowellLineTol = 1e-2;
  static constexpr int kPowellSweeps = 3;

 private:
  const Solid& solid_;
  const Samples& s_;
  std::vector<RadiusTable> tables_;
  double dr_;
  std::vector<double> prev_radius_;
  std::vector<int> member_start_, members_;
};

}  // namespace

// ---------------------------------------------------------------------------------------------
TriMesh trimesh_of(const scene::Mesh& mesh) {
  TriMesh t;
  t.positions = mesh.positions;
  t.triangles = mesh.triangles;
  check_trimesh(t, "mesh '" + mesh.name + "'");
  return weld(t);
}

double mesh_volume(const TriMesh& mesh) {
  check_trimesh(mesh, "mesh_volume");
  dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const glm::vec3& p : mesh.positions) {
    lo = glm::min(lo, dvec3(p));
    hi = glm::max(hi, dvec3(p));
  }
  const dvec3 o = 0.5 * (lo + hi);  // origin-independent for closed meshes; centred for rounding
  double v = 0.0;
  for (const glm::uvec3& t : mesh.triangles) {
    const dvec3 a = dvec3(mesh.positions[t.x]) - o, b = dvec3(mesh.positions[t.y]) - o, c = dvec3(mesh.positions[t.z]) - o;
    v += glm::dot(a, glm::cross(b, c)) / 6.0;
  }
  if (!(v > 0.0))
    throw std::invalid_argument("mesh_volume: the mesh encloses a non-positive volume (" + num(v) +
                                "): not closed, inverted winding, or flat");
  return v;
}

double sphere_outside_volume(const scene::Sphere& s, const TriMesh& mesh) {
  const dvec3 c(s.center);
  if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z) || !std::isfinite(s.radius) || s.radius < 0.0f)
    throw std::invalid_argument("sphere_outside_volume: invalid sphere centre " + vstr(c) + " radius " + num(s.radius));
  const Solid solid(mesh, "sphere_outside_volume");
  return solid.outside(c, s.radius);
}

double outside_volume_ratio(const std::vector<scene::Sphere>& spheres, const TriMesh& mesh) {
  const Solid solid(mesh, "outside_volume_ratio");
  double sum = 0.0;
  for (size_t i = 0; i < spheres.size(); ++i) {
    const scene::Sphere& s = spheres[i];
    const dvec3 c(s.center);
    if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z) || !std::isfinite(s.radius) || s.radius < 0.0f)
      throw std::invalid_argument("outside_volume_ratio: sphere " + std::to_string(i) + " is invalid: centre " + vstr(c) +
                                  " radius " + num(s.radius));
    sum += solid.outside(c, s.radius);
  }
  return sum / solid.volume();
}

std::vector<glm::dvec3> fit_sample_points(const TriMesh& mesh, const FitOptions& opt) {
  validate_options(opt);
  const Solid solid(mesh, "fit_sample_points");
  return make_samples(solid, opt, "fit_sample_points").p;
}

FitResult fit_sphere_set(const TriMesh& mesh, const FitOptions& opt,
                         const std::function<void(const FitProgress&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  validate_options(opt);
  // A caller that follows the iterations itself (fit-proxies prints each one) gets no second report.
  std::optional<Progress> bar;
  if (!progress) bar.emplace("sphere-set fit (" + std::to_string(opt.spheres) + " spheres)");
  const Solid solid(mesh, "fit_sphere_set");
  const Samples samples = make_samples(solid, opt, "fit_sphere_set");
  const size_t N = samples.p.size();
  if (static_cast<size_t>(opt.spheres) > N)
    throw std::invalid_argument("fit_sphere_set: " + std::to_string(opt.spheres) + " spheres requested but the mesh gives only " +
                                std::to_string(N) + " sample points");
  Fitter fitter(solid, samples, opt.spheres);
  FitResult res;
  res.object_volume = solid.volume();

  // Initial centres: distinct random sample points (radius 0).
  State st;
  {
    std::mt19937_64 rng(opt.seed);
    std::vector<int> idx(N);
    for (size_t i = 0; i < N; ++i) idx[i] = static_cast<int>(i);
    for (int i = 0; i < opt.spheres; ++i) {
      std::uniform_int_distribution<size_t> U(static_cast<size_t>(i), N - 1);
      std::swap(idx[i], idx[U(rng)]);
      st.centre.push_back(samples.p[idx[i]]);
    }
  }
  // Iterations against the cap: a fit that converges early jumps to 100 %.
  auto report = [&](int it, double E, const char* phase) {
    if (progress) progress(FitProgress{it, E, phase});
    if (bar) bar->update(static_cast<double>(it) / opt.max_iterations);
  };

  // Teleport attempts per stall before the fit counts as converged.
  constexpr int kTeleportAttempts = 3;
  constexpr int kTeleportRounds = 3;
  State best;
  int stall = 0;
  double last_E = std::numeric_limits<double>::infinity();
  int it = 0;
  bool converged = false;
  while (it < opt.max_iterations && !converged) {
    ++it;
    fitter.cluster(st);
    report(it, st.E, "cluster");
    fitter.update(st);
    report(it, st.E, "update");
    if (st.E < best.E) best = st;
    const bool significant = st.E < last_E * (1.0 - opt.stall_tolerance);
    last_E = std::min(last_E, st.E);
    stall = significant ? 0 : stall + 1;
    if (stall < opt.teleport_after_stall) continue;
    // Stalled: teleport from the best state; keep it if E drops, else revert (paper 004 6.2).
    converged = true;
    for (int attempt = 0; attempt < kTeleportAttempts && it < opt.max_iterations; ++attempt) {
      State trial = best;
      if (!fitter.teleport(trial, attempt)) break;
      ++res.teleports_tried;
      // A teleported pair starts from single points; give it a few rounds to settle before judging.
      State settled;
      for (int round = 0; round < kTeleportRounds && it < opt.max_iterations; ++round) {
        ++it;
        fitter.cluster(trial);
        fitter.update(trial);
        report(it, trial.E, "teleport");
        if (trial.E < settled.E) settled = trial;
      }
      trial = std::move(settled);
      if (trial.E < best.E) {
        ++res.teleports_accepted;
        best = trial;
        st = std::move(trial);
        last_E = best.E;
        stall = 0;
        converged = false;
        break;
      }
    }
  }
  res.iterations = it;

  // Float spheres that still bound every point of their cluster.
  const int K = opt.spheres;
  std::vector<double> r2(K, 0.0);
  std::vector<glm::vec3> cf(K);
  for (int i = 0; i < K; ++i) cf[i] = glm::vec3(best.centre[i]);
  for (size_t q = 0; q < N; ++q) {
    const int l = best.label[q];
    const dvec3 d = samples.p[q] - dvec3(cf[l]);
    r2[l] = std::max(r2[l], glm::dot(d, d));
  }
  res.spheres.resize(K);
  double sum = 0.0;
  for (int i = 0; i < K; ++i) {
    res.spheres[i].center = cf[i];
    res.spheres[i].radius = detail::round_radius_up(std::sqrt(r2[i]));
    sum += solid.outside(dvec3(cf[i]), res.spheres[i].radius);
  }
  res.E = sum / solid.volume();
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (bar) bar->done();
  return res;
}

// ---------------------------------------------------------------------------------------------
// Octree baseline (Hubbard 1995 as in paper 004 Figure 4).
namespace {
// Separating-axis triangle/box overlap (Akenine-Moller 2001).
bool tri_box_overlap(const dvec3& bc, const dvec3& bh, const TriD& t) {
  const dvec3 v[3] = {t.p[0] - bc, t.p[1] - bc, t.p[2] - bc};
  for (int a = 0; a < 3; ++a) {
    const double mn = std::min({v[0][a], v[1][a], v[2][a]}), mx = std::max({v[0][a], v[1][a], v[2][a]});
    if (mn > bh[a] || mx < -bh[a]) return false;
  }
  const dvec3 n = glm::cross(v[1] - v[0], v[2] - v[0]);
  if (std::abs(glm::dot(n, v[0])) > glm::dot(bh, glm::abs(n))) return false;
  const dvec3 f[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      dvec3 e(0.0);
      e[i] = 1.0;
      const dvec3 axis = glm::cross(e, f[j]);
      const double p0 = glm::dot(axis, v[0]), p1 = glm::dot(axis, v[1]), p2 = glm::dot(axis, v[2]);
      const double r = glm::dot(bh, glm::abs(axis));
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  return true;
}
}  // namespace

std::vector<scene::Sphere> octree_sphere_set(const TriMesh& mesh, int count) {
  if (count < 1 || count > 1000000)
    throw std::invalid_argument("octree_sphere_set: count = " + std::to_string(count) + " must be in [1, 1000000]");
  const Solid solid(mesh, "octree_sphere_set");
  struct Cell {
    dvec3 c;
    double half;
    int depth;
    double priority;  // V(S - T) of the cell's bounding sphere
    int order;        // creation order, for determinism
  };
  auto sphere_of = [](const Cell& c) {
    scene::Sphere s;
    s.center = glm::vec3(c.c);
    const dvec3 cf(s.center);
    double r2 = 0.0;
    for (int k = 0; k < 8; ++k) {
      const dvec3 corner = c.c + c.half * dvec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
      r2 = std::max(r2, glm::dot(corner - cf, corner - cf));
    }
    s.radius = detail::round_radius_up(std::sqrt(r2));
    return s;
  };
  auto occupied = [&](const dvec3& c, double half) {
    bool hit = false;
    solid.bvh().ball(c, half * std::sqrt(3.0), [&](int i) {
      if (!hit && tri_box_overlap(c, dvec3(half), solid.tris()[i])) hit = true;
    });
    if (hit) return true;
    solid.check_winding(c, "octree_sphere_set");
    return solid.inside(c);  // no surface in the cell: it is all inside or all outside
  };
  int order = 0;
  auto make = [&](const dvec3& c, double half, int depth) {
    Cell cell{c, half, depth, 0.0, order++};
    const scene::Sphere s = sphere_of(cell);
    cell.priority = solid.outside(dvec3(s.center), s.radius);
    return cell;
  };
  const dvec3 ext = solid.hi() - solid.lo();
  const double half = 0.5 * std::max({ext.x, ext.y, ext.z}) * (1.0 + 1e-9);
  auto cmp = [](const Cell& a, const Cell& b) {
    return a.priority != b.priority ? a.priority < b.priority : a.order > b.order;
  };
  std::priority_queue<Cell, std::vector<Cell>, decltype(cmp)> open(cmp);
  std::vector<Cell> done;
  open.push(make(0.5 * (solid.lo() + solid.hi()), half, 0));
  int total = 1;
  // Refine the cell whose sphere has the most outside volume while the count allows.
  while (!open.empty()) {
    const Cell c = open.top();
    open.pop();
    std::vector<Cell> kids;
    if (c.depth < 20) {
      const double h = 0.5 * c.half;
      for (int k = 0; k < 8; ++k) {
        const dvec3 cc = c.c + h * dvec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
        if (occupied(cc, h)) kids.push_back(make(cc, h, c.depth + 1));
      }
    }
    if (kids.empty() || total - 1 + static_cast<int>(kids.size()) > count) {
      done.push_back(c);
      continue;
    }
    total += static_cast<int>(kids.size()) - 1;
    for (const Cell& k : kids) open.push(k);
  }
  std::sort(done.begin(), done.end(), [](const Cell& a, const Cell& b) { return a.order < b.order; });
  std::vector<scene::Sphere> out;
  for (const Cell& c : done) out.push_back(sphere_of(c));
  return out;
}

}  // namespace softgi::proxies
