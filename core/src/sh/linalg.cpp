// The only translation unit of the SH core that includes Eigen: eigen-decompositions of the
// product matrix for the exact exponential (paper 004 eq. 28) and the logarithm (eqs. 30-32).
#include <Eigen/Dense>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "softgi/sh/exp_log.hpp"
#include "softgi/sh/product.hpp"

namespace softgi::sh {

namespace {
Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen_of_product_matrix(int order, const double* f) {
  const int n2 = num_coeffs(order);
  Eigen::MatrixXd m(n2, n2);
  std::vector<double> buf(static_cast<std::size_t>(n2) * n2);
  TripleProduct::get(order).product_matrix(f, buf.data());
  for (int i = 0; i < n2; ++i)
    for (int j = 0; j < n2; ++j) m(i, j) = buf[static_cast<std::size_t>(i) * n2 + j];
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(m);
  if (es.info() != Eigen::Success) throw std::runtime_error("SH product matrix eigen-decomposition did not converge");
  return es;
}
}  // namespace

void exp_exact(int order, const double* f, double* out) {
  check_order(order, "exp_exact");
  const int n2 = num_coeffs(order);
  check_finite(std::span<const double>(f, n2), "exp_exact input");
  auto es = eigen_of_product_matrix(order, f);
  const Eigen::MatrixXd& r = es.eigenvectors();  // columns: M_f = R D R^T (Eigen's R is the paper's R^T)
  Eigen::Map<const Eigen::VectorXd> fv(f, n2);
  Eigen::VectorXd rf = r.transpose() * fv;
  for (int i = 0; i < n2; ++i) {
    double x = es.eigenvalues()(i);
    // q(x) = (e^x - 1)/x, evaluated through expm1 so that small x keeps full precision.
    double q = std::abs(x) < 1e-300 ? 1.0 : std::expm1(x) / x;
    rf(i) *= q;
  }
  Eigen::VectorXd g = r * rf;
  g(0) += kSqrt4Pi;
  for (int i = 0; i < n2; ++i) {
    if (!std::isfinite(g(i))) {
      std::ostringstream os;
      os << "exp_exact: result coefficient " << i << " overflows (largest product-matrix eigenvalue "
         << es.eigenvalues().maxCoeff() << ")";
      throw std::overflow_error(os.str());
    }
    out[i] = g(i);
  }
}

void log_eigen(int order, const double* g, double* out, double threshold) {
  check_order(order, "log_eigen");
  const int n2 = num_coeffs(order);
  check_finite(std::span<const double>(g, n2), "log_eigen input");
  if (!(threshold > 0.0 && threshold < 1.0))
    throw std::invalid_argument("log_eigen: eigenvalue clip threshold " + std::to_string(threshold) + " must lie in (0, 1)");
  auto es = eigen_of_product_matrix(order, g);
  const double lmax = es.eigenvalues().maxCoeff();
  if (!(lmax > 0.0)) {
    std::ostringstream os;
    os << "log_eigen: the product matrix of g has no positive eigenvalue (max " << lmax
       << "): g is nowhere positive, its log is undefined";
    throw std::domain_error(os.str());
  }
  const double eps = threshold * lmax;  // eq. 32: clip at a fraction of the largest eigenvalue
  const Eigen::MatrixXd& r = es.eigenvectors();
  Eigen::Map<const Eigen::VectorXd> gv(g, n2);
  Eigen::VectorXd gm1 = gv;
  gm1(0) -= kSqrt4Pi;
  Eigen::VectorXd rg = r.transpose() * gm1;
  for (int i = 0; i < n2; ++i) {
    double x = std::max(es.eigenvalues()(i), eps);
    // q'(x) = log(x)/(x - 1) (eq. 31), through log1p near x = 1 where it tends to 1.
    double qp = std::abs(x - 1.0) < 1e-12 ? 1.0 : std::log1p(x - 1.0) / (x - 1.0);
    rg(i) *= qp;
  }
  Eigen::VectorXd f = r * rg;
  for (int i = 0; i < n2; ++i) out[i] = f(i);
}

}  // namespace softgi::sh
