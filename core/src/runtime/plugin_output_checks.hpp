// Plugin output checked where it enters the core (issue 20). Everything a plugin hands the loop
// passes through here once, before the archive, the dataset or a file sees it:
//  * a broken contract (a cell index outside the grid, a batch of the wrong shape, non-finite
//    parameters, latent codes, decoder outputs or reconstruction errors, an exception from plugin
//    code) is a qd::PluginError naming the component and its library; qdrun stops the run with
//    exit code 3 and the last checkpoint intact;
//  * a non-finite fitness (environment) or descriptor value (descriptor) is an outcome of that one
//    evaluation: it is counted invalid and never stored, with one warning per component and run.
#pragma once

#include "runtime/components.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/plugin_call.hpp"

#include <qd/errors.hpp>
#include <qd/mutator.hpp>
#include <qd/representation.hpp>
#include <qd/types.hpp>

#include <iosfwd>
#include <new>
#include <string>
#include <vector>

namespace qd::runtime {

class PluginOutputChecks {
 public:
  explicit PluginOutputChecks(const Components& c) : c_(c) {}

  // An evaluated batch, from any backend. Throws EvaluationFault for a cell outside [-1, cells)
  // (before the archive is touched); evaluations with a non-finite fitness or descriptor value get
  // cell -1 (invalid).
  void evaluations(Evaluations& e, int loop, int iteration);

  // mutate()'s output: `count` rows of finite parameters; for the loop's mutator also finite
  // latent origins where given (`latent` columns) and one value per declared metric.
  void offspring(const Offspring& o, bool initial, std::size_t count, std::size_t latent, int loop,
                 int iteration) const;

  // What the representation's `call` returned: `rows` x `cols`, all finite.
  void representation_output(const char* call, const Matrix& m, Eigen::Index rows, Eigen::Index cols) const;

 private:
  const Components& c_;
  bool warned_fitness_ = false, warned_descriptor_ = false;
};

// The representation as the loop and the mutators see it: every call goes to the experiment's
// representation, and what it returns is checked (shape, finite values; the Jacobians' shapes)
// before anyone uses it, so a fault is named as the representation's and not as the mutator's that
// happened to call it. Results are the representation's own, bit for bit.
class CheckedRepresentation final : public Representation {
 public:
  CheckedRepresentation(const Components& c, const PluginOutputChecks& checks) : c_(c), checks_(checks) {}

  int latent_size() const noexcept override { return c_.representation->latent_size(); }
  FitReport fit(const Dataset& data, const FitContext& ctx) override;
  void encode(const Matrix& theta, Matrix& z) const override;
  void decode(const Matrix& z, Matrix& theta) const override;
  void decoder_jacobians(const Matrix& z, std::vector<Matrix>& jacobians) const override;
  void decoder_vjp(const Matrix& z, const Matrix& v, Matrix& out) const override;
  void reconstruction_errors(const Matrix& theta, Vector& errors) const override;
  void save(std::ostream& out) const override { c_.representation->save(out); }
  void load(std::istream& in) override { c_.representation->load(in); }

 private:
  const Components& c_;
  const PluginOutputChecks& checks_;
};

// Calls plugin code that runs in qdrun's process (mutators, representations). An exception that is
// not one of the core's reports (SystemError: a write failed; PluginError; bad_alloc) is a bug of
// the plugin: it becomes a PluginError naming it and the call.
template <class F>
void call_plugin(const std::string& who, const char* call, F&& f) {
  const PluginCallScope scope(who, call);  // named if it crashes or calls exit()
  try {
    f();
  } catch (const SystemError&) {
    throw;
  } catch (const PluginError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw PluginError(who + " threw from " + call + ": " + e.what());
  } catch (...) {
    throw PluginError(who + " threw from " + call + " an exception that is not a std::exception");
  }
}

}  // namespace qd::runtime
