#include <qd/config.hpp>
#include <qd/errors.hpp>

#include <toml++/toml.h>

#include <sstream>
#include <string_view>
#include <variant>

namespace qd {

using Value = std::variant<bool, std::int64_t, double, std::string, std::vector<std::int64_t>, std::vector<double>>;

struct Config::Impl {
  struct Entry {
    std::string key;
    Value value;
    std::string where;
    bool user_set = false;
  };
  std::string table;
  std::vector<Entry> entries;

  Entry* find(const std::string& key) {
    for (auto& e : entries)
      if (e.key == key) return &e;
    return nullptr;
  }
  const Entry* find(const std::string& key) const { return const_cast<Impl*>(this)->find(key); }

  void set(const std::string& key, Value v, std::string where) {
    const bool user = where != "default";
    if (Entry* e = find(key)) {
      e->value = std::move(v);
      e->where = std::move(where);
      e->user_set = user;
    } else {
      entries.push_back({key, std::move(v), std::move(where), user});
    }
  }

  template <class T>
  const T& get(const std::string& key, const char* type_name) const {
    const Entry* e = find(key);
    if (!e) throw ConfigError(key, "[" + table + "]." + key + " is not a declared parameter (component bug)");
    if (const T* v = std::get_if<T>(&e->value)) return *v;
    throw ConfigError(key, "[" + table + "]." + key + " is not of type " + type_name + " (component bug)");
  }
};

Config::Config() : impl_(std::make_unique<Impl>()) {}
Config::Config(std::string table) : impl_(std::make_unique<Impl>()) {
  impl_->table = std::move(table);
}
Config::Config(const Config& o) : impl_(std::make_unique<Impl>(*o.impl_)) {}
Config& Config::operator=(const Config& o) {
  if (this != &o) *impl_ = *o.impl_;
  return *this;
}
Config::Config(Config&&) noexcept = default;
Config& Config::operator=(Config&&) noexcept = default;
Config::~Config() = default;

const std::string& Config::table() const noexcept {
  return impl_->table;
}

std::string Config::where(const std::string& key) const {
  const Impl::Entry* e = impl_->find(key);
  return e ? e->where : std::string("default");
}
bool Config::has(const std::string& key) const noexcept {
  return impl_->find(key) != nullptr;
}
bool Config::is_set(const std::string& key) const noexcept {
  const Impl::Entry* e = impl_->find(key);
  return e && e->user_set;
}

bool Config::get_bool(const std::string& key) const {
  return impl_->get<bool>(key, "bool");
}
std::int64_t Config::get_int(const std::string& key) const {
  return impl_->get<std::int64_t>(key, "integer");
}
double Config::get_float(const std::string& key) const {
  return impl_->get<double>(key, "float");
}
std::string Config::get_string(const std::string& key) const {
  return impl_->get<std::string>(key, "string");
}
std::vector<std::int64_t> Config::get_int_list(const std::string& key) const {
  return impl_->get<std::vector<std::int64_t>>(key, "integer list");
}
std::vector<double> Config::get_float_list(const std::string& key) const {
  return impl_->get<std::vector<double>>(key, "float list");
}

std::vector<std::string> Config::keys() const {
  std::vector<std::string> out;
  for (const auto& e : impl_->entries) out.push_back(e.key);
  return out;
}

void Config::set_bool(const std::string& k, bool v, std::string w) {
  impl_->set(k, v, std::move(w));
}
void Config::set_int(const std::string& k, std::int64_t v, std::string w) {
  impl_->set(k, v, std::move(w));
}
void Config::set_float(const std::string& k, double v, std::string w) {
  impl_->set(k, v, std::move(w));
}
void Config::set_string(const std::string& k, std::string v, std::string w) {
  impl_->set(k, std::move(v), std::move(w));
}
void Config::set_int_list(const std::string& k, std::vector<std::int64_t> v, std::string w) {
  impl_->set(k, std::move(v), std::move(w));
}
void Config::set_float_list(const std::string& k, std::vector<double> v, std::string w) {
  impl_->set(k, std::move(v), std::move(w));
}

void Config::set_from_text(const ParamSpec& spec, const std::string& text, std::string where) {
  toml::table t;
  try {
    t = toml::parse("v = " + text, std::string_view{"<default>"});
  } catch (const toml::parse_error& e) {
    throw ConfigError(spec.key,
                      "default value '" + text + "' of " + spec.key + " is not TOML: " + std::string(e.description()));
  }
  const toml::node& n = *t.get("v");
  auto bad = [&]() {
    return ConfigError(
        spec.key, std::string("default value '") + text + "' of " + spec.key + " is not a " + to_string(spec.type));
  };
  switch (spec.type) {
    case ParamType::kBool:
      if (!n.is_boolean()) throw bad();
      set_bool(spec.key, n.as_boolean()->get(), std::move(where));
      break;
    case ParamType::kInteger:
      if (!n.is_integer()) throw bad();
      set_int(spec.key, n.as_integer()->get(), std::move(where));
      break;
    case ParamType::kFloat:
      if (!n.is_number()) throw bad();
      set_float(spec.key, n.value<double>().value(), std::move(where));
      break;
    case ParamType::kString:
      if (!n.is_string()) throw bad();
      set_string(spec.key, n.as_string()->get(), std::move(where));
      break;
    case ParamType::kIntegerList: {
      if (!n.is_array()) throw bad();
      std::vector<std::int64_t> v;
      for (const auto& x : *n.as_array()) {
        if (!x.is_integer()) throw bad();
        v.push_back(x.as_integer()->get());
      }
      set_int_list(spec.key, std::move(v), std::move(where));
      break;
    }
    case ParamType::kFloatList: {
      if (!n.is_array()) throw bad();
      std::vector<double> v;
      for (const auto& x : *n.as_array()) {
        if (!x.is_number()) throw bad();
        v.push_back(x.value<double>().value());
      }
      set_float_list(spec.key, std::move(v), std::move(where));
      break;
    }
  }
}

Config defaults_of(const ParamSpec* specs, std::size_t count, const std::string& table) {
  Config c(table);
  for (std::size_t i = 0; i < count; ++i) c.set_from_text(specs[i], specs[i].default_value);
  return c;
}

}  // namespace qd
