// Configuration, stage 1: the document (config_document.hpp). Reading files and their includes,
// command-line overrides, where each key came from, and writing values back as TOML text.
#include "runtime/config_toml.hpp"

#include <qd/errors.hpp>

#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

Document::Document() : impl(std::make_unique<Impl>()) {}
Document::~Document() = default;
Document::Document(Document&&) noexcept = default;
Document& Document::operator=(Document&&) noexcept = default;

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (u < 0x20 || u == 0x7f) {  // TOML allows no control character in a basic string
      char esc[8];
      std::snprintf(esc, sizeof(esc), "\\u%04x", u);
      out += esc;
      continue;
    }
    out += c;
  }
  return out + "\"";
}

// Text for a message: control characters (a newline in a path given on the command line) shown
// as escapes, so a message stays one line.
std::string printable(const std::string& text) {
  std::string out;
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u != 0x7f) {
      out += c;
    } else {
      char esc[8];
      std::snprintf(esc, sizeof(esc), c == '\n' ? "\\n" : "\\x%02x", u);
      out += esc;
    }
  }
  return out;
}

bool has_control_character(const std::string& text) {
  return std::any_of(text.begin(), text.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u < 0x20 || u == 0x7f;
  });
}

namespace {

std::string key_text(std::string_view key) {
  const bool bare = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  return bare ? std::string(key) : toml_string(std::string(key));
}

// TOML text of a value, numbers in their shortest exact form (toml++ writes 17 significant
// digits: 0.050000000000000003 for 0.05), for config.toml and for messages.
void put_value(std::ostream& o, const toml::node& n) {
  if (const auto* f = n.as_floating_point()) {
    std::string t = format_number(f->get());
    if (t.find_first_of(".eEn") == std::string::npos) t += ".0";  // TOML: a float has a point or exponent
    o << t;
  } else if (const auto* i = n.as_integer()) {
    o << i->get();
  } else if (const auto* b = n.as_boolean()) {
    o << (b->get() ? "true" : "false");
  } else if (const auto* str = n.as_string()) {
    // A literal string where one can hold it, as toml++ writes them.
    const std::string& v = str->get();
    if (v.find('\'') == std::string::npos && !has_control_character(v))
      o << '\'' << v << '\'';
    else
      o << toml_string(v);
  } else if (const auto* a = n.as_array()) {
    o << '[';
    for (std::size_t k = 0; k < a->size(); ++k) {
      if (k) o << ", ";
      put_value(o, *a->get(k));
    }
    o << ']';
  } else if (const auto* t = n.as_table()) {
    o << '{';
    bool first = true;
    for (auto&& [k, v] : *t) {
      o << (first ? " " : ", ") << key_text(k.str()) << " = ";
      put_value(o, v);
      first = false;
    }
    o << (first ? "}" : " }");
  } else {
    n.visit([&](const auto& v) { o << v; });  // dates and times, which no parameter takes
  }
}

// A resolved configuration as TOML: each table's values, then its sub-tables under [headers].
void put_table(std::ostream& o, const toml::table& t, const std::string& prefix) {
  for (auto&& [k, v] : t) {
    if (v.is_table()) continue;
    o << key_text(k.str()) << " = ";
    put_value(o, v);
    o << '\n';
  }
  for (auto&& [k, v] : t) {
    if (!v.is_table()) continue;
    const std::string name = prefix.empty() ? key_text(k.str()) : prefix + "." + key_text(k.str());
    o << "\n[" << name << "]\n";
    put_table(o, *v.as_table(), name);
  }
}

}  // namespace

std::string value_text(const toml::node& n) {
  std::ostringstream o;
  put_value(o, n);
  return o.str();
}

std::string toml_text(const toml::table& t) {
  std::ostringstream o;
  put_table(o, t, "");
  std::string text = o.str();
  if (!text.empty() && text.front() == '\n') text.erase(0, 1);
  return text;
}

std::string location(const toml::source_region& src) {
  if (!src.path) return "<unknown>";
  const std::string& p = *src.path;
  // Command-line options (--set, --seed, --backend, --output) name themselves.
  if (p.rfind("--", 0) == 0) return printable(p);
  return p + ":" + std::to_string(src.begin.line) + ":" + std::to_string(src.begin.column);
}

std::string location(const toml::node& n) {
  return location(n.source());
}

void fail_at(const toml::node& n, const std::string& msg) {
  throw InputError(location(n) + ": " + msg);
}

const toml::table* sub_table(const toml::table& root, const char* name) {
  const toml::node* n = root.get(name);
  if (!n) return nullptr;
  if (!n->is_table()) fail_at(*n, std::string(name) + " must be a table ([" + name + "])");
  return n->as_table();
}

namespace {

// Merges `over` into `base`: tables merge key by key, everything else is replaced. Nodes are
// moved, never copied: toml++ keeps a node's source location only through moves, and every error
// message needs it.
void deep_merge(toml::table& base, toml::table&& over) {
  for (auto&& [k, v] : over) {
    if (auto* sub = v.as_table()) {
      if (auto* existing = base.get(k); existing && existing->is_table()) {
        deep_merge(*existing->as_table(), std::move(*sub));
        continue;
      }
    }
    base.insert_or_assign(k, std::move(v));
  }
}

constexpr const char* kComponentTableNames[] = {"environment", "descriptor", "representation", "mutator", "initial"};

const toml::table* table_of(const toml::table& root, const char* name) {
  const toml::node* n = root.get(name);
  return n ? n->as_table() : nullptr;
}

std::optional<std::string> type_of(const toml::table& root, const char* table) {
  const toml::table* t = table_of(root, table);
  const toml::node* type = t ? t->get("type") : nullptr;
  if (type && type->is_string()) return type->as_string()->get();
  return std::nullopt;
}

// One file's own keys, tagged with the type its table names (if any).
KeyOrigins own_origins(const toml::table& root) {
  KeyOrigins out;
  for (const char* name : kComponentTableNames) {
    const toml::table* t = table_of(root, name);
    if (!t) continue;
    const auto type = type_of(root, name);
    for (const auto& [k, v] : *t)
      if (k.str() != "type") out[name][std::string(k.str())] = {type.value_or(""), type.has_value()};
  }
  return out;
}

struct Layered {
  toml::table root;
  KeyOrigins origins;
};

// Puts `over` on top of `base` (the including file over its includes, a later include over an
// earlier one). Keys of `over` without a type of their own were written for the type below them.
void layer(Layered& base, Layered&& over) {
  for (auto& [table, keys] : over.origins) {
    const auto below = type_of(base.root, table.c_str());
    for (auto& [key, origin] : keys) {
      if (!origin.known && below) origin = {*below, true};
      base.origins[table][key] = origin;
    }
  }
  deep_merge(base.root, std::move(over.root));
}

// `chain`: the files that include this one, outermost first (an include cycle is named, not
// followed).
Layered parse_file(const fs::path& file, std::vector<fs::path>& chain) {
  std::error_code ec;
  const fs::path canonical = fs::weakly_canonical(fs::absolute(file, ec), ec);
  if (const auto seen = std::find(chain.begin(), chain.end(), canonical); seen != chain.end()) {
    std::string cycle;
    for (auto it = seen; it != chain.end(); ++it) cycle += it->string() + " -> ";
    throw InputError(file.string() + ": an include cycle (" + cycle + canonical.string() + ")");
  }
  if (chain.size() > 16) throw InputError(file.string() + ": includes nest more than 16 levels");
  const fs::file_status st = fs::status(file, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    throw InputError(file.string() + ": cannot read the experiment file: " + ec.message());
  if (!fs::exists(st)) throw InputError(file.string() + ": no such experiment file");
  // A FIFO or device would block or never end: an experiment file is a regular file (a symlink to
  // one is fine), and far smaller than this.
  if (!fs::is_regular_file(st)) throw InputError(file.string() + ": not a regular file, so not an experiment file");
  const auto size = fs::file_size(file, ec);
  if (!ec && size > kMaxTomlBytes)
    throw InputError(file.string() + ": " + std::to_string(size) + " bytes, larger than any experiment file (" +
                     std::to_string(kMaxTomlBytes >> 20) + " MB at most)");
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": cannot open experiment file: " + std::strerror(errno));
  std::stringstream ss;
  ss << in.rdbuf();
  toml::table t;
  try {
    t = toml::parse(ss.str(), file.string());
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  const toml::node* inc = t.get("include");
  if (!inc) {
    KeyOrigins origins = own_origins(t);
    return {std::move(t), std::move(origins)};
  }
  std::vector<std::string> includes;
  if (inc->is_string()) {
    includes.push_back(inc->as_string()->get());
  } else if (inc->is_array()) {
    for (const auto& x : *inc->as_array()) {
      if (!x.is_string()) fail_at(x, "include entries must be strings (paths)");
      includes.push_back(x.as_string()->get());
    }
  } else {
    fail_at(*inc, "include must be a path or a list of paths");
  }
  Layered merged;
  chain.push_back(canonical);
  for (const auto& rel : includes) {
    fs::path p = fs::path(rel).is_absolute() ? fs::path(rel) : file.parent_path() / rel;
    try {
      layer(merged, parse_file(p, chain));
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " (included from " + location(*inc) + ")");
    }
  }
  chain.pop_back();
  t.erase("include");
  KeyOrigins origins = own_origins(t);
  layer(merged, Layered{std::move(t), std::move(origins)});
  return merged;
}

}  // namespace

Document Document::read(const fs::path& file) {
  Document d;
  d.impl->file = fs::absolute(file);
  std::vector<fs::path> chain;
  Layered l = parse_file(d.impl->file, chain);
  d.impl->root = std::move(l.root);
  d.impl->origins = std::move(l.origins);
  return d;
}

Document Document::parse(const std::string& text, const std::string& source_name) {
  Document d;
  try {
    d.impl->root = toml::parse(text, source_name);
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  d.impl->origins = own_origins(d.impl->root);
  return d;
}

fs::path Document::file() const {
  return impl->file;
}

void Document::apply_override(const std::string& assignment, const std::string& option) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set " + assignment + ": expected KEY.PATH=VALUE, for example --set mutator.sigma=0.05");
  const std::string path = assignment.substr(0, eq);
  const std::string value = assignment.substr(eq + 1);
  const std::string source = option.empty() ? "--set " + assignment : option;
  toml::table parsed;
  bool bare = false;
  try {
    parsed = toml::parse("v = " + value, source);
    // TOML reads the words nan and inf as floats and 2024-01-01 as a date; no parameter takes
    // either, and --set mutator.mode=nan means the word.
    const toml::node& v = *parsed.get("v");
    bare = (v.is_floating_point() && !std::isfinite(v.as_floating_point()->get())) || v.is_date() || v.is_time() ||
           v.is_date_time();
  } catch (const toml::parse_error&) {
    bare = true;  // --set mutator.type=iso
  }
  if (bare) {
    try {
      parsed = toml::parse("v = " + toml_string(value), source);
    } catch (const toml::parse_error& e) {
      throw InputError(printable(source) + ": the value cannot be read: " + std::string(e.description()));
    }
  }
  std::vector<std::string> parts;
  for (std::size_t pos = 0;;) {
    const std::size_t dot = path.find('.', pos);
    parts.push_back(path.substr(pos, dot == std::string::npos ? std::string::npos : dot - pos));
    if (dot == std::string::npos) break;
    pos = dot + 1;
  }
  for (const auto& part : parts)
    if (part.empty()) throw InputError(printable(source) + ": empty key");
  toml::table* t = &impl->root;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    toml::node* n = t->get(parts[i]);
    if (!n) {
      // Made by parsing, so that an error about the table (an unknown one) names this option.
      toml::table made = toml::parse("t = {}", source);
      t->insert_or_assign(parts[i], std::move(*made.get("t")));
      n = t->get(parts[i]);
    }
    if (!n->is_table()) throw InputError(printable(source) + ": '" + parts[i] + "' is not a table");
    t = n->as_table();
  }
  t->insert_or_assign(parts.back(), std::move(*parsed.get("v")));
  // A key given on the command line is always checked against the final component; a new type
  // leaves the keys already there tagged with the old one.
  if (parts.size() == 2 && parts[1] != "type") impl->origins[parts[0]][parts[1]] = KeyOrigin{};
}

void Document::set_string(const std::string& path, const std::string& value, const std::string& option) {
  apply_override(path + "=" + toml_string(value), option);
}

void Document::set_integer(const std::string& path, std::int64_t value, const std::string& option) {
  apply_override(path + "=" + std::to_string(value), option);
}

namespace {
// The entries of [plugins] `key` (a path or a list of paths), made absolute against `file`'s
// directory. Checks every key of [plugins].
std::vector<std::string> plugin_dirs(const toml::table& root, const fs::path& file, const std::string& key) {
  std::vector<std::string> out;
  const toml::table* t = sub_table(root, "plugins");
  if (!t) return out;
  for (const auto& [k, v] : *t) {
    if (k.str() != "path" && k.str() != "search_path")
      fail_at(v, "unknown key '" + std::string(k.str()) + "' in [plugins]; it accepts: path, search_path");
    if (k.str() != key) continue;
    auto add = [&](const toml::node& x) {
      if (!x.is_string()) fail_at(x, "plugins." + key + " entries must be strings");
      fs::path p = x.as_string()->get();
      if (p.is_relative() && !file.empty()) p = file.parent_path() / p;
      out.push_back(p.lexically_normal().string());
    };
    if (v.is_array()) {
      for (const auto& x : *v.as_array()) add(x);
    } else {
      add(v);
    }
  }
  return out;
}
}  // namespace

std::vector<std::string> Document::plugin_paths() const {
  return plugin_dirs(impl->root, impl->file, "path");
}

std::vector<std::string> Document::recorded_search_path() const {
  return plugin_dirs(impl->root, impl->file, "search_path");
}
namespace {
void flatten(const toml::table& t, const std::string& prefix, std::map<std::string, std::string>& out) {
  for (const auto& [key, node] : t) {
    const std::string path = prefix.empty() ? std::string(key.str()) : prefix + "." + std::string(key.str());
    if (const toml::table* sub = node.as_table()) {
      flatten(*sub, path, out);
    } else {
      out[path] = value_text(node);
    }
  }
}
}  // namespace

std::map<std::string, std::string> config_values(const std::string& toml, const std::string& source) {
  std::map<std::string, std::string> out;
  try {
    flatten(toml::parse(toml, source), "", out);
  } catch (const toml::parse_error& e) {
    throw InputError(location(e.source()) + ": malformed TOML: " + std::string(e.description()));
  }
  return out;
}

std::vector<ConfigDifference> config_differences(const std::string& before, const std::string& after) {
  const std::map<std::string, std::string> a = config_values(before, "checkpoint"),
                                           b = config_values(after, "config.toml");
  std::vector<ConfigDifference> out;
  for (const auto& [key, value] : a) {
    const auto it = b.find(key);
    if (it == b.end())
      out.push_back({key, value, "(absent)"});
    else if (it->second != value)
      out.push_back({key, value, it->second});
  }
  for (const auto& [key, value] : b)
    if (a.count(key) == 0) out.push_back({key, "(absent)", value});
  return out;
}

bool may_change_on_resume(const std::string& key) {
  for (const char* prefix : {"evaluation.", "output.", "plugins."})
    if (key.rfind(prefix, 0) == 0) return true;
  return key == "experiment.loops";
}

}  // namespace qd::runtime
