#include <cmath>
#include <cstdio>
#include <softgi/sh/exp_log.hpp>
#include <softgi/sh/product.hpp>
#include <softgi/sh/tables.hpp>

// Exercises the installed headers and library: a product, a table and an exponential.
int main() {
  using namespace softgi::sh;
  const TripleProduct& tp = TripleProduct::get(4);
  ShTables tables(TableOptions{4, 32, TableParam::Theta, 0.02, false});
  std::vector<double> f(16, 0.0), g(16, 0.0);
  auto log_cap = cap_log_zh(4, 0.5);
  for (int l = 0; l < 4; ++l) f[index(l, 0)] = log_cap[l];
  exp_hyb(tables, f.data(), g.data());
  auto vis = cap_visibility_zh(4, 0.5);
  double err = std::abs(g[0] - vis[0]);
  std::printf("nonzeros=%zu exp(log(cap)) DC error=%g\n", tp.nonzeros_ordered(), err);
  return (tp.nonzeros_ordered() == 353 && err < 0.05) ? 0 : 1;
}
