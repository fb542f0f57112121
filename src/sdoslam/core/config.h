#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "sdoslam/core/error.h"

namespace sdoslam {

// A YAML mapping read key by key. Every key read is remembered; RejectUnknownKeys() then throws
// for the first key nobody asked for, so that a misspelt setting is an error instead of a silent
// fall-back to its default (ORB-SLAM2's scar). Messages name file, line and the dotted key.
class ConfigMap {
 public:
  // Parses `path`; its root must be a mapping. Throws Error naming the file (and line).
  static ConfigMap LoadFile(const std::filesystem::path& path);
  // Parses YAML text (for tests and command-line overrides); `origin` names it in messages.
  static ConfigMap LoadString(const std::string& text, const std::string& origin);

  ConfigMap(YAML::Node node, std::string origin, std::string prefix);

  bool Has(const std::string& key) const;

  // Reads an optional scalar: leaves *value untouched when the key is absent.
  template <typename T>
  void Read(const std::string& key, T* value) {
    const YAML::Node child = Child(key);
    if (!child) return;
    if (!child.IsScalar()) throw Error(Where(child) + Path(key) + ": expected a single value");
    try {
      *value = child.as<T>();
    } catch (const YAML::Exception&) {
      throw Error(Where(child) + Path(key) + ": cannot read '" + child.Scalar() + "' as " +
                  TypeName<T>());
    }
  }

  // Reads an optional list of text values ([a, b] or a block sequence).
  void ReadList(const std::string& key, std::vector<std::string>* values);

  // Nested mapping `key`, or nullopt when absent. Throws when present but not a mapping.
  std::optional<ConfigMap> Section(const std::string& key);

  void RejectUnknownKeys() const;

  const std::string& origin() const { return origin_; }

 private:
  YAML::Node Child(const std::string& key);
  std::string Path(const std::string& key) const { return prefix_ + key; }
  std::string Where(const YAML::Node& node) const;

  template <typename T>
  static const char* TypeName() {
    if constexpr (std::is_same_v<T, bool>) return "true/false";
    if constexpr (std::is_integral_v<T>) return "an integer";
    if constexpr (std::is_floating_point_v<T>) return "a number";
    return "text";
  }

  YAML::Node node_;
  std::string origin_;
  std::string prefix_;  // "camera." for keys below camera:
  std::set<std::string> used_;
};

// Options structs list their settings once, in
//   template <class Options, class Visitor> static void VisitFields(Options& o, Visitor&& visit)
// which calls visit("key", o.member) for every setting. The config's YAML paths are these keys:
// a member that has VisitFields itself is a nested section, and OptionGroup puts some of a
// struct's members into a section of their own without a struct for them. ReadFields,
// WriteFields and ListFields drive the one list for reading, writing and naming the keys.
template <class F>
struct OptionGroup {
  F members;  // members(visit) visits the group's settings
};
template <class F>
OptionGroup(F) -> OptionGroup<F>;

namespace options_detail {

struct NoVisit {
  template <class T>
  void operator()(const char*, T&&) const {}
};
template <class T>
struct IsGroup : std::false_type {};
template <class F>
struct IsGroup<OptionGroup<F>> : std::true_type {};

}  // namespace options_detail

template <class T>
concept OptionsStruct = requires(std::remove_cvref_t<T>& o) {
  std::remove_cvref_t<T>::VisitFields(o, options_detail::NoVisit{});
};

// Reads every setting of `options` present in `section` (nested sections recursively, each
// checked for unknown keys); absent ones keep their values. `section`'s own unknown keys are
// left to the caller, who may read other keys there.
class FieldReader {
 public:
  explicit FieldReader(ConfigMap& section) : section_(section) {}
  template <class T>
  void operator()(const char* key, T&& value) {
    using V = std::remove_cvref_t<T>;
    if constexpr (options_detail::IsGroup<V>::value || OptionsStruct<V>) {
      if (std::optional<ConfigMap> sub = section_.Section(key)) {
        FieldReader reader(*sub);
        if constexpr (options_detail::IsGroup<V>::value) {
          value.members(reader);
        } else {
          V::VisitFields(value, reader);
        }
        sub->RejectUnknownKeys();
      }
    } else if constexpr (std::is_same_v<V, std::vector<std::string>>) {
      section_.ReadList(key, &value);
    } else if constexpr (std::is_same_v<V, std::filesystem::path>) {
      std::string text = value.string();
      section_.Read(key, &text);
      value = text;
    } else {
      section_.Read(key, &value);
    }
  }

 private:
  ConfigMap& section_;
};

template <OptionsStruct Options>
void ReadFields(ConfigMap& section, Options* options) {
  Options::VisitFields(*options, FieldReader(section));
}

// Writes every setting as key: value into an open YAML mapping, nested sections as mappings.
class FieldWriter {
 public:
  explicit FieldWriter(YAML::Emitter* out) : out_(*out) {}
  template <class T>
  void operator()(const char* key, T&& value) {
    using V = std::remove_cvref_t<T>;
    out_ << YAML::Key << key << YAML::Value;
    if constexpr (options_detail::IsGroup<V>::value) {
      out_ << YAML::BeginMap;
      value.members(*this);
      out_ << YAML::EndMap;
    } else if constexpr (OptionsStruct<V>) {
      out_ << YAML::BeginMap;
      V::VisitFields(value, *this);
      out_ << YAML::EndMap;
    } else if constexpr (std::is_same_v<V, std::vector<std::string>>) {
      out_ << YAML::Flow << value;
    } else if constexpr (std::is_same_v<V, std::filesystem::path>) {
      out_ << value.string();
    } else {
      out_ << value;
    }
  }

 private:
  YAML::Emitter& out_;
};

template <OptionsStruct Options>
void WriteFields(const Options& options, YAML::Emitter* out) {
  Options::VisitFields(options, FieldWriter(out));
}

// Calls visit(path, member) for every setting, path the dotted key below `prefix` ("a.b.c"):
// for listing the keys, and for tests that go through every setting.
template <class Visitor>
class PathVisitor {
 public:
  PathVisitor(std::string prefix, Visitor& visit) : prefix_(std::move(prefix)), visit_(visit) {}
  template <class T>
  void operator()(const char* key, T&& value) {
    using V = std::remove_cvref_t<T>;
    const std::string path = prefix_ + key;
    if constexpr (options_detail::IsGroup<V>::value) {
      value.members(PathVisitor(path + ".", visit_));
    } else if constexpr (OptionsStruct<V>) {
      V::VisitFields(value, PathVisitor(path + ".", visit_));
    } else {
      visit_(path, value);
    }
  }

 private:
  std::string prefix_;
  Visitor& visit_;
};

template <OptionsStruct Options, class Visitor>
void VisitPaths(Options& options, const std::string& prefix, Visitor&& visit) {
  std::remove_const_t<Options>::VisitFields(
      options, PathVisitor<std::remove_reference_t<Visitor>>(prefix, visit));
}

// Every setting's dotted path below `prefix`, in visiting order.
template <OptionsStruct Options>
std::vector<std::string> ListFields(const std::string& prefix = "") {
  std::vector<std::string> keys;
  const Options defaults;
  VisitPaths(defaults, prefix, [&](const std::string& path, const auto&) { keys.push_back(path); });
  return keys;
}

}  // namespace sdoslam
