#pragma once
// Errors a user can cause (files, config, devices) are values, never aborts.
// A message names the file, the place in it and what was expected, e.g.
//   "rig.yaml:12:5: /cameras/0/exposure_us: expected a number > 0, got 'fast'".

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace lifmcr {

struct Error {
  std::string message;
};

// "<file>:<line>:<column>: <what>", leaving out the parts that are unknown (0).
Error MakeError(const std::string& file, int line, int column, const std::string& what);
// "<file>: <where>: <what>" for formats addressed by path (XML elements, YAML keys).
Error MakeErrorAt(const std::string& file, const std::string& where, const std::string& what);

// A value or the error that prevented it.
template <typename T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : data_(std::move(value)) {}      // NOLINT: implicit by design
  Expected(Error error) : data_(std::move(error)) {}  // NOLINT
  bool ok() const { return data_.index() == 0; }
  explicit operator bool() const { return ok(); }
  T& value() & { return std::get<0>(data_); }
  const T& value() const& { return std::get<0>(data_); }
  T&& value() && { return std::get<0>(std::move(data_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  const Error& error() const { return std::get<1>(data_); }

 private:
  std::variant<T, Error> data_;
};

// Success, or the error that prevented it.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)) {}  // NOLINT: implicit by design
  static Status Ok() { return Status(); }
  bool ok() const { return !error_.has_value(); }
  explicit operator bool() const { return ok(); }
  const Error& error() const { return *error_; }

 private:
  std::optional<Error> error_;
};

}  // namespace lifmcr
