#pragma once
// Validating YAML reading: every value read knows its key path
// ("/cameras/1/exposure_us") and where it sits in the file, so every error a
// user can cause reads
//   <file>:<line>:<col>: <key path>: <what was expected>, got <what was found>
// (MakeError of config/error.h). yaml-cpp stays behind this header: callers
// see YamlNode and YamlMap only.
//
// Reading is "sticky": the first error is kept in a YamlErrors and every later
// read becomes a no-op, so a loader reads straight through and checks once at
// the end. Optional keys leave their output untouched when absent, so the
// defaults live once, in the default member initialisers of the structs read.
//
// What counts as which type (YAML 1.2 core schema, strictly):
//   string   any scalar, plain or quoted, taken verbatim ("0042" stays "0042")
//   integer  a plain scalar of decimal digits with an optional sign
//   number   a plain scalar that is a finite decimal or integer number
//   bool     a plain `true` or `false`
// A quoted scalar ("100") is a string, never a number; a key with no value is
// null and is a type error, never "use the default".

#include "config/error.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr {

// The first error of a read; later errors are dropped (they are often
// consequences of the first).
class YamlErrors {
 public:
  void Add(Error error) {
    if (!first_) first_ = std::move(error);
  }
  bool ok() const { return !first_.has_value(); }
  Status status() const { return first_ ? Status(*first_) : Status::Ok(); }

 private:
  std::optional<Error> first_;
};

// One node of a parsed document: a cheap, copyable handle.
class YamlNode {
 public:
  // Parses one YAML document. Malformed YAML, more than one document, or
  // nesting deeper than yaml-cpp's depth guard (which itself says only "bad
  // file") is an error at the line and column yaml-cpp reports. `label` names the
  // source (usually the file path) in every message.
  static Expected<YamlNode> Parse(std::string_view text, const std::string& label);

  const std::string& label() const;
  // "/" for the root, "/cameras/0/serial" below it.
  std::string path() const;
  int line() const;    // 1-based, 0 when unknown
  int column() const;  // 1-based, 0 when unknown

  bool IsMap() const;
  bool IsList() const;
  bool IsScalar() const;
  bool IsNull() const;
  bool IsQuoted() const;              // a single- or double-quoted scalar
  const std::string& Scalar() const;  // empty unless IsScalar()
  // For messages: 'text' / "text" (shortened), a map, a list, nothing (null).
  std::string Describe() const;

  // Elements of a list with paths /<path>/<i>; empty unless IsList().
  std::vector<YamlNode> Elements() const;

  // "<label>:<line>:<col>: <path>: <what>" at this node.
  Error ErrorHere(const std::string& what) const;
  // The same for a path below this node, e.g. "/cameras/1/serial" from the
  // root: positioned at the deepest node of `path` that exists, but naming
  // `path` itself. This is how cross-field checks done on plain structs get
  // their line and column back.
  Error ErrorAtPath(std::string_view path, const std::string& what) const;

  struct Impl;  // holds the yaml-cpp node; defined in yaml_reader.cpp

 private:
  explicit YamlNode(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
  std::shared_ptr<const Impl> impl_;
  friend class YamlMap;
};

// Whether a key must be present.
enum class Presence { kRequired, kOptional };

// Reads the keys of one map node. Keys asked for (by any method below) are
// the known keys; Finish() reports the first key that is not known, listing
// the known ones. A node that is not a map, a key that is not a scalar and a
// key given twice are errors, reported when the YamlMap is built.
class YamlMap {
 public:
  YamlMap(const YamlNode& node, YamlErrors* errors);

  const YamlNode& node() const { return node_; }
  bool ok() const { return errors_->ok(); }

  // Marks `key` known and returns its value node when present.
  std::optional<YamlNode> Child(std::string_view key, Presence presence);

  void Read(std::string_view key, std::string* out, Presence presence);
  void Read(std::string_view key, int* out, Presence presence);
  void Read(std::string_view key, std::int64_t* out, Presence presence);
  void Read(std::string_view key, double* out, Presence presence);
  void Read(std::string_view key, bool* out, Presence presence);
  // A list of exactly `count` numbers ("[x, y]"); an error names the element.
  void ReadNumbers(std::string_view key, std::size_t count, std::vector<double>* out,
                   Presence presence);

  // An enumeration spelt as one of `names` ("a|b|c"); `parse` maps a name to
  // std::optional<Enum>. A bad name lists the allowed ones.
  template <typename Enum, typename ParseFn>
  void ReadEnum(std::string_view key, Enum* out, ParseFn parse, std::string_view names,
                Presence presence) {
    std::optional<YamlNode> value = ScalarChild(key, presence, "one of " + std::string(names));
    if (!value) return;
    if (const auto parsed = parse(value->Scalar())) {
      *out = *parsed;
    } else {
      Fail(*value, "expected one of " + std::string(names) + ", got " + value->Describe());
    }
  }

  // A nested map, empty (and an error recorded) when the value is not a map.
  std::optional<YamlMap> Map(std::string_view key, Presence presence);
  // The elements of a list value.
  std::optional<std::vector<YamlNode>> List(std::string_view key, Presence presence);

  // Records an error at `at` unless one is recorded already.
  void Fail(const YamlNode& at, const std::string& what);
  // Reports the first unknown key. Call after every known key was asked for.
  void Finish();

 private:
  // The value of `key` when it is a scalar; records a type error otherwise.
  std::optional<YamlNode> ScalarChild(std::string_view key, Presence presence,
                                      const std::string& expected);

  YamlNode node_;
  YamlErrors* errors_;
  std::set<std::string, std::less<>> known_;
  std::vector<std::string> known_in_order_;
};

}  // namespace lifmcr
