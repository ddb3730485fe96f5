// `softgi tables`: the precomputed SH tables and the triple-product tensor, as text or JSON.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.hpp"
#include "softgi/sh/product.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::app {

namespace {
// Paper 004 section 3 table: nonzero entries of the triple-product tensor per order n = 1..8.
constexpr int kPaperTripleCounts[9] = {0, 1, 10, 83, 369, 1164, 2961, 6586, 13018};

struct TablesArgs {
  int order = 4;
  int resolution = 256;
  std::string param = "theta";
  double log_threshold = 0.02;
  bool json = false;
  bool exact_operator = false;
};

nlohmann::json rows_of(const sh::Table1D& t) {
  nlohmann::json a = nlohmann::json::array();
  for (int k = 0; k < t.rows(); ++k) a.push_back(std::vector<double>(t.row(k), t.row(k) + t.width));
  return a;
}

void run_tables(const TablesArgs& args) {
  sh::TableOptions opt;
  opt.order = args.order;
  opt.resolution = args.resolution;
  opt.log_threshold = args.log_threshold;
  opt.exact_indirect_operator = args.exact_operator;
  if (args.param == "theta") opt.param = sh::TableParam::Theta;
  else if (args.param == "alpha") opt.param = sh::TableParam::Alpha;
  else throw std::invalid_argument("--param must be theta or alpha, got '" + args.param + "'");
  sh::check_order(opt.order, "softgi tables --order");
  if (opt.order < 2) throw std::invalid_argument("softgi tables --order: SH order " + std::to_string(opt.order) + " is outside [2, 8]");

  auto t0 = std::chrono::steady_clock::now();
  const sh::TripleProduct& tp = sh::TripleProduct::get(opt.order);
  sh::ShTables tables(opt);
  double build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  std::vector<double> theta;
  for (double x : tables.cap_visibility().x) theta.push_back(opt.param == sh::TableParam::Theta ? x : std::asin(std::min(1.0, x)));

  if (args.json) {
    nlohmann::json j;
    j["order"] = opt.order;
    j["coefficients"] = opt.order * opt.order;
    j["resolution"] = opt.resolution;
    j["param"] = args.param;
    j["log_threshold"] = opt.log_threshold;
    j["triple_product_nonzeros"] = tp.nonzeros_ordered();
    j["triple_product_nonzeros_unique"] = tp.nonzeros_unique();
    j["triple_product_nonzeros_structural"] = tp.nonzeros_structural();
    j["triple_product_nonzeros_paper"] = kPaperTripleCounts[opt.order];
    j["table_bytes"] = tables.bytes();
    j["build_ms"] = build_ms;
    nlohmann::json t;
    t["theta"] = theta;
    t["cap_visibility_zh"] = rows_of(tables.cap_visibility());
    t["cap_log_zh"] = rows_of(tables.cap_log());
    t["ol_norm"] = tables.ol_norm();
    t["ol_a"] = tables.ol_a();
    t["ol_b"] = tables.ol_b();
    nlohmann::json d3 = nlohmann::json::array();
    for (double th : theta) {
      auto d = sh::indirect_D_closed_form(std::sin(th));
      d3.push_back(std::vector<double>(d.begin(), d.end()));
    }
    t["D_averaged"] = d3;
    t["D_averaged_full"] = rows_of(tables.D_averaged());
    t["D_polynomial"] = rows_of(tables.D_polynomial());
    t["spherical_light_w"] = rows_of(tables.sl_weight());
    j["tables"] = t;
    j["interpolation_error"] = {{"cap_visibility_zh", tables.cap_visibility().max_interp_error},
                                {"cap_log_zh", tables.cap_log().max_interp_error},
                                {"D_averaged", tables.D_averaged().max_interp_error},
                                {"D_polynomial", tables.D_polynomial().max_interp_error},
                                {"spherical_light_w", tables.sl_weight().max_interp_error},
                                {"ol_ab", tables.ol_interp_error()}};
    if (args.exact_operator) j["interpolation_error"]["M_exact"] = tables.M_exact().max_interp_error;
    j["ol_monotone_max_norm"] = tables.ol_max_norm();
    std::cout << j.dump(1) << "\n";
    return;
  }

  std::cout << std::setprecision(6);
  std::cout << "softgi SH tables, order n = " << opt.order << " (" << opt.order * opt.order << " coefficients), "
            << opt.resolution << " samples uniform in " << args.param << ", built in " << std::fixed
            << std::setprecision(1) << build_ms << " ms\n"
            << std::defaultfloat << std::setprecision(6);
  std::cout << "triple-product tensor: " << tp.nonzeros_ordered() << " nonzero entries over ordered (i,j,k); "
            << tp.nonzeros_structural() << " allowed by the selection rules (paper 004 table: "
            << kPaperTripleCounts[opt.order] << "); " << tp.nonzeros_unique() << " stored (i<=j<=k); product "
            << tp.product_flops() << " flops, square " << tp.square_flops() << " flops\n";
  std::cout << "table memory: " << tables.bytes() << " bytes (double)\n";
  auto where = [&](const sh::Table1D& t) {
    std::ostringstream os;
    os << t.max_interp_error << "  at " << args.param << " = "
       << (opt.param == sh::TableParam::Theta ? t.max_interp_error_at * 180.0 / sh::kPi : t.max_interp_error_at)
       << (opt.param == sh::TableParam::Theta ? " deg" : "");
    return os.str();
  };
  std::cout << "max linear-interpolation error at sample midpoints:\n"
            << "  cap visibility ZH " << where(tables.cap_visibility()) << "\n"
            << "  cap log ZH        " << where(tables.cap_log()) << "\n"
            << "  D averaged        " << where(tables.D_averaged()) << "\n"
            << "  spherical light w " << where(tables.sl_weight()) << "\n"
            << "  OL a, b           " << tables.ol_interp_error() << "\n";
  if (args.exact_operator) std::cout << "  exact operator M  " << where(tables.M_exact()) << "\n";
  std::cout << "OL table monotone in ||f^|| up to " << tables.ol_max_norm() << " (clamped beyond)\n\n";
  std::cout << " theta(deg)  cap_vis[0..2]                     cap_log[0..2]                     ||f^||     a        b        D(avg)[0..2]\n";
  for (double deg : {1.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 89.0}) {
    double th = deg * sh::kPi / 180.0;
    auto g = sh::cap_visibility_zh(opt.order, th);
    auto f = sh::cap_log_zh(opt.order, th, opt.log_threshold);
    double ff = 0;
    for (int l = 1; l < opt.order; ++l) ff += f[l] * f[l];
    double a, b;
    tables.ol_lookup(std::sqrt(ff), a, b);
    auto d = sh::indirect_D_closed_form(std::sin(th));
    std::cout << std::fixed << std::setprecision(4) << std::setw(10) << deg << "  ";
    for (int l = 0; l < 3; ++l) std::cout << std::setw(9) << g[l] << " ";
    std::cout << "  ";
    for (int l = 0; l < 3; ++l) std::cout << std::setw(9) << f[l] << " ";
    std::cout << "  " << std::setw(8) << std::sqrt(ff) << " " << std::setw(8) << a << " " << std::setw(8) << b << "  ";
    for (int l = 0; l < 3; ++l) std::cout << std::setw(8) << d[l] << " ";
    std::cout << "\n";
  }
  std::cout << std::defaultfloat;
}
}  // namespace

namespace {
void register_tables(CLI::App& app) {
  auto args = std::make_shared<TablesArgs>();
  CLI::App* sub = app.add_subcommand("tables", "Print the precomputed SH tables and the triple-product tensor size");
  sub->add_option("--order", args->order, "SH order n (2..8)")->check(CLI::Range(2, 8));
  sub->add_option("--resolution", args->resolution, "samples per table")->check(CLI::Range(2, 65536));
  sub->add_option("--param", args->param, "table parameter: theta or alpha (= sin theta)")
      ->check(CLI::IsMember({"theta", "alpha"}));
  sub->add_option("--log-threshold", args->log_threshold, "eigenvalue clip for SH log, fraction of the largest (paper: 0.02)")
      ->check(CLI::Range(1e-6, 0.999));
  sub->add_flag("--json", args->json, "print JSON instead of the text summary");
  sub->add_flag("--exact-operator", args->exact_operator, "also tabulate the exact indirect operator M(theta) (n^4 per sample)");
  sub->callback([args] { run_tables(*args); });
}
const CommandRegistrar registrar(register_tables);
}  // namespace

}  // namespace softgi::app
