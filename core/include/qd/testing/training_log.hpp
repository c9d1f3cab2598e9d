// A TrainingLog that keeps the logs in memory, for representation tests (FitContext::log).
// Header-only: it is compiled into the test that uses it.
#pragma once

#include <qd/representation.hpp>

#include <map>
#include <string>

namespace qd::testing {

class MemoryLog final : public TrainingLog {
 public:
  void append(const std::string& name, const std::string& header, const std::string& rows) override {
    std::string& text = logs_[name];
    if (text.empty()) text = header;
    text += rows;
  }
  // The text of log `name` as the run directory would hold it ("" when never written).
  std::string text(const std::string& name) const {
    const auto it = logs_.find(name);
    return it == logs_.end() ? std::string() : it->second;
  }
  std::size_t count() const noexcept { return logs_.size(); }

 private:
  std::map<std::string, std::string> logs_;
};

}  // namespace qd::testing
