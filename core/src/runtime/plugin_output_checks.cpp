#include "runtime/plugin_output_checks.hpp"

#include "runtime/number_text.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

namespace qd::runtime {

namespace {

std::string where(int loop, int iteration) {
  return "loop " + std::to_string(loop) + ", iteration " + std::to_string(iteration);
}

// Without an early exit the compiler vectorises this loop; Eigen's allFinite() checks one value at a
// time and cost 3 % of a Striker ps-uniform run (200 x 1 635 parameters per batch).
bool all_finite(const double* x, std::size_t n) {
  std::size_t non_finite = 0;
  for (std::size_t i = 0; i < n; ++i) non_finite += !(std::abs(x[i]) <= std::numeric_limits<double>::max());
  return non_finite == 0;
}

// The first non-finite entry of `m` as (row, column), or false.
bool first_non_finite(const Matrix& m, Eigen::Index& row, Eigen::Index& col) {
  if (all_finite(m.data(), static_cast<std::size_t>(m.size()))) return false;
  for (row = 0; row < m.rows(); ++row)
    for (col = 0; col < m.cols(); ++col)
      if (!std::isfinite(m(row, col))) return true;
  return false;
}

std::string shape_of(const Matrix& m) {
  return std::to_string(m.rows()) + " x " + std::to_string(m.cols());
}

void warn_once(bool& warned, const std::string& text) {
  if (warned) return;
  warned = true;
  std::fprintf(stderr, "qdrun: warning: %s (counted invalid and never stored; shown once per run)\n", text.c_str());
  std::fflush(stderr);
}

}  // namespace

void PluginOutputChecks::evaluations(Evaluations& e, int loop, int iteration) {
  const std::int64_t cells = c_.grid.cells;
  const auto dims = e.descriptors.cols();
  for (std::size_t k = 0; k < e.cells.size(); ++k) {
    const std::int64_t cell = e.cells[k];
    if (cell < -1 || cell >= cells)
      throw EvaluationFault(c_.descriptor_label + " returned cell " + std::to_string(cell) +
                                ", outside its grid's [0, " + std::to_string(cells) +
                                ") (-1 marks a trace it cannot describe)",
                            k, k);
    if (cell < 0) continue;
    const auto row = static_cast<Eigen::Index>(k);
    if (!std::isfinite(e.fitness[k])) {
      warn_once(warned_fitness_, c_.environment_label + " returned fitness " + format_number(e.fitness[k]) +
                                     " for offspring " + std::to_string(k) + " of " + where(loop, iteration));
      e.cells[k] = -1;
      continue;
    }
    for (Eigen::Index d = 0; d < dims; ++d)
      if (!std::isfinite(e.descriptors(row, d))) {
        warn_once(warned_descriptor_, c_.descriptor_label + " returned descriptor value " +
                                          format_number(e.descriptors(row, d)) + " (dimension " + std::to_string(d) +
                                          ") for offspring " + std::to_string(k) + " of " + where(loop, iteration));
        e.cells[k] = -1;
        break;
      }
  }
}

void PluginOutputChecks::offspring(const Offspring& o, bool initial, std::size_t count, std::size_t latent, int loop,
                                   int iteration) const {
  const std::string& who = initial ? c_.initial_label : c_.mutator_label;
  const auto P = static_cast<Eigen::Index>(c_.shape.param_count());
  const auto n = static_cast<Eigen::Index>(count);
  if (o.theta.rows() != n || o.theta.cols() != P)
    throw PluginError(who + " returned offspring of shape " + shape_of(o.theta) + " in " + where(loop, iteration) +
                      ", expected " + std::to_string(n) + " x " + std::to_string(P));
  Eigen::Index r = 0, col = 0;
  if (first_non_finite(o.theta, r, col))
    throw PluginError(who + " returned parameter " + format_number(o.theta(r, col)) + " (offspring " +
                      std::to_string(r) + ", parameter " + std::to_string(col) + ") in " + where(loop, iteration));
  if (initial) return;  // loop 0 reads nothing else
  if (o.has_latent.size() != count)
    throw PluginError(who + " returned " + std::to_string(o.has_latent.size()) + " has_latent flags for " +
                      std::to_string(count) + " offspring in " + where(loop, iteration));
  if (o.metrics.size() != c_.metric_names.size())
    throw PluginError(who + " returned " + std::to_string(o.metrics.size()) + " metrics, but declares " +
                      std::to_string(c_.metric_names.size()) + " in metric_names(), in " + where(loop, iteration));
  if (latent == 0) return;
  const auto L = static_cast<Eigen::Index>(latent);
  if (o.latent.rows() != n || o.latent.cols() != L)
    throw PluginError(who + " returned latent codes of shape " + shape_of(o.latent) + " in " + where(loop, iteration) +
                      ", expected " + std::to_string(n) + " x " + std::to_string(L));
  for (Eigen::Index k = 0; k < n; ++k) {
    if (!o.has_latent[static_cast<std::size_t>(k)] || o.latent.row(k).allFinite()) continue;
    throw PluginError(who + " returned a non-finite latent origin for offspring " + std::to_string(k) + " in " +
                      where(loop, iteration));
  }
}

void PluginOutputChecks::representation_output(const char* call, const Matrix& m, Eigen::Index rows,
                                               Eigen::Index cols) const {
  if (m.rows() != rows || m.cols() != cols)
    throw PluginError(c_.representation_label + " " + call + " returned " + shape_of(m) + ", expected " +
                      std::to_string(rows) + " x " + std::to_string(cols));
  Eigen::Index r = 0, col = 0;
  if (first_non_finite(m, r, col))
    throw PluginError(c_.representation_label + " " + call + " returned " + format_number(m(r, col)) + " (row " +
                      std::to_string(r) + ", column " + std::to_string(col) + ")");
}

FitReport CheckedRepresentation::fit(const Dataset& data, const FitContext& ctx) {
  FitReport report;
  call_plugin(c_.representation_label, "fit()", [&] { report = c_.representation->fit(data, ctx); });
  return report;
}

void CheckedRepresentation::encode(const Matrix& theta, Matrix& z) const {
  call_plugin(c_.representation_label, "encode()", [&] { c_.representation->encode(theta, z); });
  checks_.representation_output("encode()", z, theta.rows(), latent_size());
}

void CheckedRepresentation::decode(const Matrix& z, Matrix& theta) const {
  call_plugin(c_.representation_label, "decode()", [&] { c_.representation->decode(z, theta); });
  checks_.representation_output("decode()", theta, z.rows(), static_cast<Eigen::Index>(c_.shape.param_count()));
}

void CheckedRepresentation::decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const {
  call_plugin(c_.representation_label, "decoder_jacobians()",
              [&] { c_.representation->decoder_jacobians(z, jacobians); });
  // Shapes only: the Jacobians are as large as the work that made them.
  const auto P = static_cast<Eigen::Index>(c_.shape.param_count());
  if (jacobians.size() != static_cast<std::size_t>(z.rows()))
    throw PluginError(c_.representation_label + " decoder_jacobians() returned " + std::to_string(jacobians.size()) +
                      " Jacobians for " + std::to_string(z.rows()) + " latent points");
  for (const Matrix& j : jacobians)
    if (j.rows() != P || j.cols() != latent_size())
      throw PluginError(c_.representation_label + " decoder_jacobians() returned a " + shape_of(j) +
                        " Jacobian, expected " + std::to_string(P) + " x " + std::to_string(latent_size()));
}

void CheckedRepresentation::decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const {
  call_plugin(c_.representation_label, "decoder_vjp()", [&] { c_.representation->decoder_vjp(z, v, out); });
  checks_.representation_output("decoder_vjp()", out, z.rows(), latent_size());
}

void CheckedRepresentation::reconstruction_errors(const Matrix& theta, Vector& errors) const {
  call_plugin(c_.representation_label, "reconstruction_errors()",
              [&] { c_.representation->reconstruction_errors(theta, errors); });
  if (errors.size() != theta.rows())
    throw PluginError(c_.representation_label + " reconstruction_errors() returned " + std::to_string(errors.size()) +
                      " values for " + std::to_string(theta.rows()) + " policies");
  for (Eigen::Index k = 0; k < errors.size(); ++k)
    if (!std::isfinite(errors[k]))
      throw PluginError(c_.representation_label + " reconstruction_errors() returned " + format_number(errors[k]) +
                        " for policy " + std::to_string(k));
}

}  // namespace qd::runtime
