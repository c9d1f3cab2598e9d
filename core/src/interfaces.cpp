// Key functions of the interfaces (pinning their type information in libqd_core) and defaults.
#include <qd/archive.hpp>
#include <qd/component.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/errors.hpp>
#include <qd/mutator.hpp>
#include <qd/planning.hpp>
#include <qd/plugin.hpp>
#include <qd/representation.hpp>

#include <cmath>

namespace qd {

Component::~Component() = default;
ArchiveView::~ArchiveView() = default;
Environment::~Environment() = default;
Descriptor::~Descriptor() = default;
Representation::~Representation() = default;
Mutator::~Mutator() = default;

bool Environment::draw_svg(const Trace&, std::ostream&) const {
  return false;
}
void Environment::save(std::ostream&) const {}
void Environment::load(std::istream&) {}

void Representation::decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const {
  QD_CHECK(z.rows() == v.rows(), "decoder_vjp: z and v must have the same number of rows");
  std::vector<Matrix> jac;
  decoder_jacobians(z, jac);
  // Plugin output: checked before it is indexed (issue 20).
  if (jac.size() != static_cast<std::size_t>(z.rows()))
    throw PluginError("the representation's decoder_jacobians() returned " + std::to_string(jac.size()) +
                      " Jacobians for " + std::to_string(z.rows()) + " latent points");
  for (const Matrix& j : jac)
    if (j.rows() != v.cols() || j.cols() != z.cols())
      throw PluginError("the representation's decoder_jacobians() returned a " + std::to_string(j.rows()) + " x " +
                        std::to_string(j.cols()) + " Jacobian, expected " + std::to_string(v.cols()) + " x " +
                        std::to_string(z.cols()));
  out.resize(z.rows(), z.cols());
  for (Eigen::Index i = 0; i < z.rows(); ++i) out.row(i).noalias() = v.row(i) * jac[static_cast<std::size_t>(i)];
}

void Representation::reconstruction_errors(const Matrix& theta, Vector& errors) const {
  Matrix z, rec;
  encode(theta, z);
  if (z.rows() != theta.rows())
    throw PluginError("the representation's encode() returned " + std::to_string(z.rows()) + " rows for " +
                      std::to_string(theta.rows()) + " policies");
  decode(z, rec);
  if (rec.rows() != theta.rows() || rec.cols() != theta.cols())
    throw PluginError("the representation's decode() returned " + std::to_string(rec.rows()) + " x " +
                      std::to_string(rec.cols()) + " for " + std::to_string(theta.rows()) + " x " +
                      std::to_string(theta.cols()) + " policies");
  errors = (theta - rec).rowwise().norm();
}

double ArchiveView::coverage() const noexcept {
  return static_cast<double>(size()) / static_cast<double>(cells());
}

double ArchiveView::mean_recn_error() const {
  const std::size_t n = size();
  double sum = 0.0;
  for (std::size_t slot = 0; slot < n; ++slot) sum += recn_error(slot);
  return n == 0 ? 0.0 : sum / static_cast<double>(n);
}

FitTimeEstimate::~FitTimeEstimate() = default;

const char* to_string(Outcome outcome) noexcept {
  switch (outcome) {
    case Outcome::kNewCell:
      return "new cell";
    case Outcome::kImproved:
      return "improved";
    case Outcome::kReplaced:
      return "replaced";
    case Outcome::kDiscarded:
      return "discarded";
    case Outcome::kInvalid:
      return "invalid";
  }
  return "unknown";
}

void Mutator::begin_loop(const LoopContext&) {}
void Mutator::feedback(const Feedback&) {}
void Mutator::save(std::ostream&) const {}
void Mutator::load(std::istream&) {}

void Offspring::reset(std::size_t count, std::size_t params, std::size_t latent_size) {
  theta.resize(static_cast<Eigen::Index>(count), static_cast<Eigen::Index>(params));
  latent.resize(static_cast<Eigen::Index>(latent_size ? count : 0), static_cast<Eigen::Index>(latent_size));
  has_latent.assign(count, 0);
  metrics.clear();
}

const char* to_string(EvalStatus status) noexcept {
  switch (status) {
    case EvalStatus::kOk:
      return "ok";
    case EvalStatus::kInvalidAction:
      return "invalid-action";
    case EvalStatus::kDiverged:
      return "diverged";
    case EvalStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

const char* to_string(Kind kind) noexcept {
  switch (kind) {
    case Kind::kEnvironment:
      return "environment";
    case Kind::kDescriptor:
      return "descriptor";
    case Kind::kRepresentation:
      return "representation";
    case Kind::kMutator:
      return "mutator";
  }
  return "unknown";
}

const char* to_string(ParamType type) noexcept {
  switch (type) {
    case ParamType::kBool:
      return "bool";
    case ParamType::kInteger:
      return "integer";
    case ParamType::kFloat:
      return "float";
    case ParamType::kString:
      return "string";
    case ParamType::kIntegerList:
      return "integer list";
    case ParamType::kFloatList:
      return "float list";
  }
  return "unknown";
}

}  // namespace qd
