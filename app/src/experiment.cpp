#include "experiment.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>

namespace softgi::app::experiment {

double median(std::vector<double> v) {
  if (v.empty()) throw std::invalid_argument("median of an empty sample");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Mask surface_mask(const render::GBuffer& gb) {
  Mask m{gb.width, gb.height, std::vector<std::uint8_t>(gb.object.size(), 0)};
  for (std::size_t i = 0; i < gb.object.size(); ++i) m.on[i] = gb.hit(i) ? 1 : 0;
  return m;
}

Mask object_mask(const render::GBuffer& gb, const scene::Scene& scene, const scene::PosedScene& posed,
                 const std::string& ground_node, std::string& chosen) {
  int object = -1;
  for (std::size_t k = 0; k < posed.objects.size(); ++k) {
    const int node = posed.objects[k].node;
    if (node >= 0 && static_cast<std::size_t>(node) < scene.nodes.size() && scene.nodes[node].name == ground_node) {
      object = static_cast<int>(k);
      chosen = "object " + std::to_string(k) + " (node '" + ground_node + "')";
      break;
    }
  }
  if (object < 0) {
    std::map<int, long long> seen;
    for (std::size_t i = 0; i < gb.object.size(); ++i)
      if (gb.hit(i)) ++seen[gb.object[i]];
    long long best = 0;
    for (const auto& [o, n] : seen)
      if (n > best) best = n, object = o;
    if (object < 0) throw std::runtime_error("ground mask: the camera sees no surface");
    chosen = "object " + std::to_string(object) + " (no node named '" + ground_node + "': the object seen in most pixels)";
  }
  Mask m{gb.width, gb.height, std::vector<std::uint8_t>(gb.object.size(), 0)};
  long long n = 0;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    m.on[i] = gb.object[i] == object ? 1 : 0;
    n += m.on[i];
  }
  if (n == 0) throw std::runtime_error("ground mask: " + chosen + " is not visible from the camera");
  return m;
}

Mask silhouette_band(const render::GBuffer& gb, double rel_jump, int radius) {
  if (!(rel_jump > 0.0) || radius < 0) throw std::invalid_argument("silhouette_band: rel_jump must be > 0 and radius >= 0");
  const int w = gb.width, h = gb.height;
  std::vector<std::uint8_t> edge(static_cast<std::size_t>(w) * h, 0);
  auto idx = [w](int x, int y) { return static_cast<std::size_t>(y) * w + x; };
  auto jump = [&](std::size_t p, std::size_t q) {
    if (gb.hit(p) != gb.hit(q)) return true;
    if (!gb.hit(p)) return false;
    const double zp = gb.depth[p], zq = gb.depth[q];
    return std::abs(zp - zq) > rel_jump * std::min(zp, zq);
  };
  // Both pixels of a jumping pair are discontinuity pixels.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t p = idx(x, y);
      if (x + 1 < w && jump(p, idx(x + 1, y))) edge[p] = edge[idx(x + 1, y)] = 1;
      if (y + 1 < h && jump(p, idx(x, y + 1))) edge[p] = edge[idx(x, y + 1)] = 1;
    }
  // Separable Chebyshev dilation: rows, then columns.
  std::vector<std::uint8_t> rows(edge.size(), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (edge[idx(x, y)])
        for (int d = std::max(0, x - radius); d <= std::min(w - 1, x + radius); ++d) rows[idx(d, y)] = 1;
  Mask m{w, h, std::vector<std::uint8_t>(edge.size(), 0)};
  for (int x = 0; x < w; ++x)
    for (int y = 0; y < h; ++y)
      if (rows[idx(x, y)])
        for (int d = std::max(0, y - radius); d <= std::min(h - 1, y + radius); ++d) m.on[idx(x, d)] = 1;
  for (std::size_t i = 0; i < m.on.size(); ++i) m.on[i] = m.on[i] && gb.hit(i);
  return m;
}

long long count(const Mask& m, int w, int h) {
  if (m.on.empty()) return static_cast<long long>(w) * h;
  long long n = 0;
  for (auto v : m.on) n += v ? 1 : 0;
  return n;
}

SquaredSums squared_sums(const Image& a, const Image& b, const Mask& mask) {
  if (a.width != b.width || a.height != b.height || a.rgb.size() != b.rgb.size())
    throw std::invalid_argument("squared_sums: image sizes differ (" + std::to_string(a.width) + "x" + std::to_string(a.height) +
                                " vs " + std::to_string(b.width) + "x" + std::to_string(b.height) + ")");
  if (!mask.on.empty() && mask.on.size() != a.rgb.size()) throw std::invalid_argument("squared_sums: mask size differs");
  SquaredSums s;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    if (!mask.on.empty() && !mask.on[i]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = static_cast<double>(a.rgb[i][c]) - b.rgb[i][c];
      s.diff += d * d;
      s.ref += static_cast<double>(b.rgb[i][c]) * b.rgb[i][c];
    }
  }
  return s;
}

double relative_squared_error(const Image& a, const Image& b, const Mask& mask) {
  const SquaredSums s = squared_sums(a, b, mask);
  if (s.ref > 0.0) return s.diff / s.ref;
  return s.diff > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
}

double error_share(const Image& a, const Image& b, const Mask& inner, const Mask& outer) {
  const double total = squared_sums(a, b, outer).diff;
  return total > 0.0 ? squared_sums(a, b, inner).diff / total : 0.0;
}

Image masked(Image img, const Mask& m) {
  if (m.on.empty()) return img;
  for (std::size_t i = 0; i < img.rgb.size(); ++i)
    if (!m.on[i]) img.rgb[i] = glm::vec3(0.0f);
  return img;
}

// --- line plot ------------------------------------------------------------------------------------

namespace {

// 3x5 glyphs, one row per entry, bit 2 = left column.
const std::map<char, std::array<int, 5>>& font() {
  static const std::map<char, std::array<int, 5>> f = {
      {'0', {7, 5, 5, 5, 7}}, {'1', {2, 6, 2, 2, 7}}, {'2', {7, 1, 7, 4, 7}}, {'3', {7, 1, 7, 1, 7}},
      {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 7, 1, 7}}, {'6', {7, 4, 7, 5, 7}}, {'7', {7, 1, 1, 1, 1}},
      {'8', {7, 5, 7, 5, 7}}, {'9', {7, 5, 7, 1, 7}}, {'.', {0, 0, 0, 0, 2}}, {'-', {0, 0, 7, 0, 0}},
      {'e', {0, 7, 7, 4, 7}}, {'+', {0, 2, 7, 2, 0}}};
  return f;
}

void put(Image& img, int x, int y, const glm::vec3& c) {
  if (x >= 0 && y >= 0 && x < img.width && y < img.height) img.at(x, y) = c;
}

// Text with its top-left corner at (x, y), glyphs scaled by `s`.
void text(Image& img, int x, int y, const std::string& s, int scale, const glm::vec3& c) {
  for (char ch : s) {
    auto it = font().find(ch);
    if (it != font().end())
      for (int r = 0; r < 5; ++r)
        for (int col = 0; col < 3; ++col)
          if (it->second[r] & (4 >> col))
            for (int dy = 0; dy < scale; ++dy)
              for (int dx = 0; dx < scale; ++dx) put(img, x + col * scale + dx, y + r * scale + dy, c);
    x += 4 * scale;
  }
}
int text_width(const std::string& s, int scale) { return static_cast<int>(s.size()) * 4 * scale - scale; }

std::string label(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

// A disc of radius `r` pixels.
void dot(Image& img, double x, double y, double r, const glm::vec3& c) {
  for (int py = static_cast<int>(std::floor(y - r)); py <= static_cast<int>(std::ceil(y + r)); ++py)
    for (int px = static_cast<int>(std::floor(x - r)); px <= static_cast<int>(std::ceil(x + r)); ++px)
      if ((px - x) * (px - x) + (py - y) * (py - y) <= r * r) put(img, px, py, c);
}

}  // namespace

Image line_plot(const std::vector<Series>& series, const PlotAxes& ax) {
  if (!(ax.x_max > ax.x_min) || !(ax.y_max > ax.y_min) || !(ax.x_step > 0) || !(ax.y_step > 0) || ax.width < 64 ||
      ax.height < 64 || ax.width > 8192 || ax.height > 8192)
    throw std::invalid_argument("line_plot: bad axes (need x_max > x_min, y_max > y_min, steps > 0, 64..8192 pixels)");
  const glm::vec3 white(1.0f), grid(0.85f), black(0.0f);
  Image img(ax.width, ax.height, white);
  constexpr int kScale = 2;  // font scale: 6x10 pixel glyphs
  const int left = 64, right = 16, top = 16, bottom = 40;
  const int x0 = left, x1 = ax.width - right, y0 = ax.height - bottom, y1 = top;  // y grows downwards
  auto px = [&](double x) { return x0 + (x - ax.x_min) / (ax.x_max - ax.x_min) * (x1 - x0); };
  auto py = [&](double y) {
    y = std::clamp(y, ax.y_min, ax.y_max);
    return y0 - (y - ax.y_min) / (ax.y_max - ax.y_min) * (y0 - y1);
  };
  const int nx = static_cast<int>(std::floor((ax.x_max - ax.x_min) / ax.x_step + 1e-9));
  const int ny = static_cast<int>(std::floor((ax.y_max - ax.y_min) / ax.y_step + 1e-9));
  if (nx > 200 || ny > 200) throw std::invalid_argument("line_plot: more than 200 grid lines");
  for (int i = 0; i <= nx; ++i) {
    const double v = ax.x_min + i * ax.x_step;
    const int X = static_cast<int>(std::lround(px(v)));
    for (int y = y1; y <= y0; ++y) put(img, X, y, grid);
    const std::string s = label(v);
    text(img, X - text_width(s, kScale) / 2, y0 + 8, s, kScale, black);
  }
  for (int i = 0; i <= ny; ++i) {
    const double v = ax.y_min + i * ax.y_step;
    const int Y = static_cast<int>(std::lround(py(v)));
    for (int x = x0; x <= x1; ++x) put(img, x, Y, grid);
    const std::string s = label(v);
    text(img, x0 - 6 - text_width(s, kScale), Y - 5, s, kScale, black);
  }
  for (int x = x0; x <= x1; ++x) put(img, x, y0, black);
  for (int y = y1; y <= y0; ++y) put(img, x0, y, black);
  for (const Series& s : series) {
    if (s.x.size() != s.y.size()) throw std::invalid_argument("line_plot: a series has different x and y counts");
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const double X = px(s.x[i]), Y = py(s.y[i]);
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) put(img, static_cast<int>(std::lround(X)) + dx, static_cast<int>(std::lround(Y)) + dy, s.colour);
      if (i + 1 < s.x.size() && std::isfinite(s.x[i + 1]) && std::isfinite(s.y[i + 1])) {
        const double X2 = px(s.x[i + 1]), Y2 = py(s.y[i + 1]);
        const int steps = static_cast<int>(std::ceil(2.0 * std::hypot(X2 - X, Y2 - Y))) + 1;
        for (int k = 0; k <= steps; ++k) {
          const double t = static_cast<double>(k) / steps;
          dot(img, X + t * (X2 - X), Y + t * (Y2 - Y), 1.2, s.colour);
        }
      }
    }
  }
  return img;
}

}  // namespace softgi::app::experiment
