// A well-formed plugin: a representation whose latent size is configurable (for the "latent larger
// than the parameter count" check) and a mutator that counts its live instances (lifetime tests).
#include <qd/plugin.hpp>

#include <atomic>

namespace {
std::atomic<int> g_live{0};

constexpr qd::ParamSpec kLatentParams[] = {qd::param_int("latent", "4", 0, 1e9, "latent size to report")};

class FixedLatent final : public qd::Representation {
 public:
  FixedLatent(const qd::Config& c, const qd::BuildContext&) : latent_(static_cast<int>(c.get_int("latent"))) {}
  int latent_size() const noexcept override { return latent_; }
  qd::FitReport fit(const qd::Dataset&, const qd::FitContext&) override { return {}; }
  void encode(const qd::Matrix& t, qd::Matrix& z) const override { z = t.leftCols(latent_); }
  void decode(const qd::Matrix& z, qd::Matrix& t) const override { t = z; }
  void decoder_jacobians(const qd::Matrix&, std::vector<qd::Matrix>&) const override {}
  void save(std::ostream&) const override {}
  void load(std::istream&) override {}

 private:
  int latent_;
};

class Counted final : public qd::Mutator {
 public:
  Counted(const qd::Config&, const qd::BuildContext&) { ++g_live; }
  ~Counted() override { --g_live; }
  void mutate(const qd::Parents& p, std::size_t, qd::MutateContext&, qd::Offspring& out) override {
    out.theta = p.theta;
  }
};
}  // namespace

extern "C" BOOST_SYMBOL_EXPORT int qd_test_live_instances() {
  return g_live.load();
}

QD_PLUGIN("good", "1.2.3",
          qd::component<FixedLatent>(qd::Kind::kRepresentation, "test-fixed-latent", "test", kLatentParams),
          qd::component<Counted>(qd::Kind::kMutator, "test-counted", "test"))
