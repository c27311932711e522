#include "config/yaml_reader.h"

#include "config/decimal_number.h"
#include "config/input_file.h"
#include "config/text_escape.h"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <sstream>

namespace lifmcr {

struct YamlNode::Impl {
  YAML::Node node;
  std::shared_ptr<const std::string> label;
  std::string path;  // "" for the root
  // Used when yaml-cpp gives the node no position (an empty value): the
  // position of its key, or of its parent.
  YAML::Mark fallback_mark;
};

namespace {

bool HasPosition(const YAML::Mark& mark) { return mark.line >= 0 && mark.column >= 0; }

// yaml-cpp places an empty value (`key:`) at the token after it, often on
// the next line, so a null value is reported at its key instead.
YAML::Mark MarkOf(const YamlNode::Impl& impl) {
  const YAML::Mark mark = impl.node.Mark();
  if (impl.node.IsNull() && HasPosition(impl.fallback_mark)) return impl.fallback_mark;
  return HasPosition(mark) ? mark : impl.fallback_mark;
}

std::string Shorten(const std::string& text) { return Excerpt(text); }

// Splits "/a/0/b" into {"a", "0", "b"}.
std::vector<std::string> SplitPath(std::string_view path) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (start <= path.size()) {
    const std::size_t slash = path.find('/', start);
    const std::size_t end = slash == std::string_view::npos ? path.size() : slash;
    if (end > start) parts.emplace_back(path.substr(start, end - start));
    if (slash == std::string_view::npos) break;
    start = slash + 1;
  }
  return parts;
}

// Counts documents without building them, recording where the second
// starts: how a second document is found without YAML::LoadAll.
class DocumentCounter : public YAML::EventHandler {
 public:
  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents == 2) second = mark;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}

  int documents = 0;
  YAML::Mark second = YAML::Mark::null_mark();
};

}  // namespace

Expected<YamlNode> YamlNode::Parse(std::string_view text, const std::string& label) {
  if (Status s = CheckTextEncoding(text, label, "YAML"); !s) return s.error();
  auto shared_label = std::make_shared<const std::string>(label);
  try {
    // Not YAML::LoadAll: yaml-cpp 0.7 loops forever there, allocating, when
    // a document starts with ',' (jbeder/yaml-cpp#1040, fixed upstream in
    // PR #1319; found by tests/fuzz/fuzz_rig_yaml). Each HandleNextDocument
    // returns, so at most two calls: the document, then whether another
    // follows.
    std::istringstream count_stream{std::string(text)};
    YAML::Parser counter_parser(count_stream);
    DocumentCounter counter;
    for (int call = 0; call < 2 && counter_parser.HandleNextDocument(counter); ++call) {
    }
    if (counter.documents > 1) {
      const YAML::Mark mark = counter.second;
      return MakeError(label, HasPosition(mark) ? mark.line + 1 : 0,
                       HasPosition(mark) ? mark.column + 1 : 0,
                       "a second YAML document (or a stray ',' that yaml-cpp reads as one) starts here; "
                       "expected one document");
    }
    auto impl = std::make_shared<Impl>();
    impl->node = counter.documents == 0 ? YAML::Node(YAML::NodeType::Null)
                                        : YAML::Load(std::string(text));
    impl->label = std::move(shared_label);
    impl->fallback_mark = YAML::Mark();  // line 1, column 1
    return YamlNode(std::move(impl));
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's depth guard says only "bad file" (its ErrorMsg::BAD_FILE).
    const bool known = HasPosition(e.mark);
    return MakeError(label, known ? e.mark.line + 1 : 0, known ? e.mark.column + 1 : 0,
                     "YAML nested " + std::to_string(e.depth()) +
                         " levels deep here, more than the YAML reader takes; expected a "
                         "file nested a few levels deep, as every lifmcr file is");
  } catch (const YAML::Exception& e) {
    // e.msg is yaml-cpp's text without its own "yaml-cpp: error at line..." prefix.
    const bool known = HasPosition(e.mark);
    return MakeError(label, known ? e.mark.line + 1 : 0, known ? e.mark.column + 1 : 0,
                     "malformed YAML: " + Excerpt(e.msg, 200));
  } catch (const std::exception& e) {
    return MakeError(label, 0, 0, std::string("malformed YAML: ") + e.what());
  }
}

const std::string& YamlNode::label() const { return *impl_->label; }
std::string YamlNode::path() const { return impl_->path.empty() ? "/" : impl_->path; }
int YamlNode::line() const {
  const YAML::Mark mark = MarkOf(*impl_);
  return HasPosition(mark) ? mark.line + 1 : 0;
}
int YamlNode::column() const {
  const YAML::Mark mark = MarkOf(*impl_);
  return HasPosition(mark) ? mark.column + 1 : 0;
}

bool YamlNode::IsMap() const { return impl_->node.IsMap(); }
bool YamlNode::IsList() const { return impl_->node.IsSequence(); }
bool YamlNode::IsScalar() const { return impl_->node.IsScalar(); }
bool YamlNode::IsNull() const { return !impl_->node.IsDefined() || impl_->node.IsNull(); }
// yaml-cpp tags a quoted scalar "!" (non-specific) and a plain one "?".
bool YamlNode::IsQuoted() const { return IsScalar() && impl_->node.Tag() == "!"; }

const std::string& YamlNode::Scalar() const {
  static const std::string kEmpty;
  return IsScalar() ? impl_->node.Scalar() : kEmpty;
}

std::string YamlNode::Describe() const {
  if (IsMap()) return "a map";
  if (IsList()) return "a list";
  if (IsNull()) return "nothing (null)";
  if (IsQuoted()) return "the string \"" + Shorten(Scalar()) + "\"";
  return "'" + Shorten(Scalar()) + "'";
}

std::vector<YamlNode> YamlNode::Elements() const {
  std::vector<YamlNode> elements;
  if (!IsList()) return elements;
  const YAML::Mark parent_mark = MarkOf(*impl_);
  for (std::size_t i = 0; i < impl_->node.size(); ++i) {
    auto impl = std::make_shared<Impl>();
    impl->node = impl_->node[i];
    impl->label = impl_->label;
    impl->path = impl_->path + "/" + std::to_string(i);
    impl->fallback_mark = parent_mark;
    elements.push_back(YamlNode(std::move(impl)));
  }
  return elements;
}

Error YamlNode::ErrorHere(const std::string& what) const {
  return MakeError(label(), line(), column(), path() + ": " + what);
}

Error YamlNode::ErrorAtPath(std::string_view path, const std::string& what) const {
  YAML::Node current = impl_->node;
  YAML::Mark mark = MarkOf(*impl_);
  for (const std::string& part : SplitPath(path)) {
    YAML::Node next;
    if (current.IsMap()) {
      for (auto it = current.begin(); it != current.end(); ++it) {
        if (it->first.IsScalar() && it->first.Scalar() == part) {
          next = it->second;
          if (HasPosition(it->first.Mark())) mark = it->first.Mark();
          break;
        }
      }
    } else if (current.IsSequence()) {
      std::size_t index = 0;
      const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), index);
      if (ec == std::errc() && end == part.data() + part.size() && index < current.size()) {
        next = current[index];
      }
    }
    if (!next.IsDefined()) break;
    current = next;
    if (!current.IsNull() && HasPosition(current.Mark())) mark = current.Mark();
  }
  const bool known = HasPosition(mark);
  return MakeError(label(), known ? mark.line + 1 : 0, known ? mark.column + 1 : 0,
                   std::string(path) + ": " + what);
}

YamlMap::YamlMap(const YamlNode& node, YamlErrors* errors) : node_(node), errors_(errors) {
  if (!node_.IsMap()) {
    Fail(node_, "expected a map, got " + node_.Describe());
    return;
  }
  // yaml-cpp keeps both entries of a repeated key; the second would be
  // silently ignored by a lookup, so it is an error here.
  std::map<std::string, int, std::less<>> first_line;
  for (auto it = node_.impl_->node.begin(); it != node_.impl_->node.end(); ++it) {
    const YAML::Mark mark = it->first.Mark();
    const int line = HasPosition(mark) ? mark.line + 1 : 0;
    const int column = HasPosition(mark) ? mark.column + 1 : 0;
    if (!it->first.IsScalar()) {
      errors_->Add(MakeError(node_.label(), line, column,
                             node_.path() + ": expected a plain key, got a complex key"));
      return;
    }
    const std::string& key = it->first.Scalar();
    const auto [previous, inserted] = first_line.emplace(key, line);
    if (!inserted) {
      errors_->Add(MakeError(node_.label(), line, column,
                             node_.impl_->path + "/" + Excerpt(key) + ": duplicate key '" + Excerpt(key) +
                                 "' (first given at line " + std::to_string(previous->second) +
                                 ")"));
      return;
    }
  }
}

std::optional<YamlNode> YamlMap::Child(std::string_view key, Presence presence) {
  if (known_.insert(std::string(key)).second) known_in_order_.emplace_back(key);
  if (!ok() || !node_.IsMap()) return std::nullopt;
  for (auto it = node_.impl_->node.begin(); it != node_.impl_->node.end(); ++it) {
    if (!it->first.IsScalar() || it->first.Scalar() != key) continue;
    auto impl = std::make_shared<YamlNode::Impl>();
    impl->node = it->second;
    impl->label = node_.impl_->label;
    impl->path = node_.impl_->path + "/" + std::string(key);
    impl->fallback_mark = it->first.Mark();
    return YamlNode(std::move(impl));
  }
  if (presence == Presence::kRequired) {
    const std::string path = node_.impl_->path + "/" + std::string(key);
    errors_->Add(MakeError(node_.label(), node_.line(), node_.column(),
                           path + ": missing required key '" + std::string(key) + "'"));
  }
  return std::nullopt;
}

std::optional<YamlNode> YamlMap::ScalarChild(std::string_view key, Presence presence,
                                             const std::string& expected) {
  std::optional<YamlNode> value = Child(key, presence);
  if (!value) return std::nullopt;
  if (!value->IsScalar()) {
    Fail(*value, "expected " + expected + ", got " + value->Describe());
    return std::nullopt;
  }
  return value;
}

void YamlMap::Read(std::string_view key, std::string* out, Presence presence) {
  if (const auto value = ScalarChild(key, presence, "a string")) *out = value->Scalar();
}

void YamlMap::Read(std::string_view key, std::int64_t* out, Presence presence) {
  const auto value = ScalarChild(key, presence, "an integer");
  if (!value) return;
  std::string_view text = value->Scalar();
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  std::int64_t parsed = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), parsed);
  if (value->IsQuoted() || text.empty() || ec != std::errc() || end != text.data() + text.size()) {
    Fail(*value, ec == std::errc::result_out_of_range
                     ? "expected an integer that fits 64 bits, got " + value->Describe()
                     : "expected an integer, got " + value->Describe());
    return;
  }
  *out = parsed;
}

void YamlMap::Read(std::string_view key, int* out, Presence presence) {
  std::int64_t wide = *out;
  Read(key, &wide, presence);
  if (!ok()) return;
  if (wide < std::numeric_limits<int>::min() || wide > std::numeric_limits<int>::max()) {
    Fail(*Child(key, presence),
         "expected an integer in [-2147483648, 2147483647], got " + std::to_string(wide));
    return;
  }
  *out = static_cast<int>(wide);
}

namespace {

// A plain scalar that is a finite decimal number.
bool ParseNumberNode(const YamlNode& value, double* out) {
  if (!value.IsScalar() || value.IsQuoted()) return false;
  std::string_view text = value.Scalar();
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double parsed = 0.0;
  const auto [end, ec] = FromCharsRounded(text.data(), text.data() + text.size(), parsed);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(parsed)) {
    return false;
  }
  *out = parsed;
  return true;
}

}  // namespace

void YamlMap::Read(std::string_view key, double* out, Presence presence) {
  const auto value = ScalarChild(key, presence, "a number");
  if (!value) return;
  if (!ParseNumberNode(*value, out)) Fail(*value, "expected a finite number, got " + value->Describe());
}

void YamlMap::ReadNumbers(std::string_view key, std::size_t count, std::vector<double>* out,
                          Presence presence) {
  const std::optional<std::vector<YamlNode>> elements = List(key, presence);
  if (!elements) return;
  if (elements->size() != count) {
    Fail(*Child(key, presence), "expected a list of " + std::to_string(count) +
                                    " numbers, got " + std::to_string(elements->size()) +
                                    " elements");
    return;
  }
  std::vector<double> values(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (!ParseNumberNode((*elements)[i], &values[i])) {
      Fail((*elements)[i], "expected a finite number, got " + (*elements)[i].Describe());
      return;
    }
  }
  *out = std::move(values);
}

void YamlMap::Read(std::string_view key, bool* out, Presence presence) {
  const auto value = ScalarChild(key, presence, "true or false");
  if (!value) return;
  if (!value->IsQuoted() && value->Scalar() == "true") {
    *out = true;
  } else if (!value->IsQuoted() && value->Scalar() == "false") {
    *out = false;
  } else {
    Fail(*value, "expected true or false, got " + value->Describe());
  }
}

std::optional<YamlMap> YamlMap::Map(std::string_view key, Presence presence) {
  std::optional<YamlNode> value = Child(key, presence);
  if (!value) return std::nullopt;
  YamlMap map(*value, errors_);
  if (!ok()) return std::nullopt;
  return map;
}

std::optional<std::vector<YamlNode>> YamlMap::List(std::string_view key, Presence presence) {
  std::optional<YamlNode> value = Child(key, presence);
  if (!value) return std::nullopt;
  if (!value->IsList()) {
    Fail(*value, "expected a list, got " + value->Describe());
    return std::nullopt;
  }
  return value->Elements();
}

void YamlMap::Fail(const YamlNode& at, const std::string& what) {
  errors_->Add(at.ErrorHere(what));
}

void YamlMap::Finish() {
  if (!ok()) return;
  for (auto it = node_.impl_->node.begin(); it != node_.impl_->node.end(); ++it) {
    const std::string& key = it->first.Scalar();
    if (known_.contains(key)) continue;
    std::string allowed;
    for (const std::string& name : known_in_order_) allowed += (allowed.empty() ? "" : ", ") + name;
    const YAML::Mark mark = it->first.Mark();
    errors_->Add(MakeError(node_.label(), HasPosition(mark) ? mark.line + 1 : 0,
                           HasPosition(mark) ? mark.column + 1 : 0,
                           node_.impl_->path + "/" + Excerpt(key) + ": unknown key '" + Excerpt(key) +
                               "', expected one of: " + allowed));
    return;
  }
}

}  // namespace lifmcr
