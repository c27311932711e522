#include "replay/xml_util.h"

#include "config/decimal_number.h"
#include "config/text_escape.h"

#include <tinyxml2.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

namespace lifmcr::xml {
namespace {

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

std::string_view Trim(std::string_view text) {
  while (!text.empty() && IsSpace(text.front())) text.remove_prefix(1);
  while (!text.empty() && IsSpace(text.back())) text.remove_suffix(1);
  return text;
}

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

// True when `text` is exactly [+-]? (d+ (. d*)? | . d+) ([eE] [+-]? d+)?.
// Checked by hand because strtod/from_chars also take hex, inf and nan.
bool IsDecimalNumber(std::string_view text) {
  size_t i = 0;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
  size_t mantissa_digits = 0;
  while (i < text.size() && IsDigit(text[i])) ++i, ++mantissa_digits;
  if (i < text.size() && text[i] == '.') {
    ++i;
    while (i < text.size() && IsDigit(text[i])) ++i, ++mantissa_digits;
  }
  if (mantissa_digits == 0) return false;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
    size_t exponent_digits = 0;
    while (i < text.size() && IsDigit(text[i])) ++i, ++exponent_digits;
    if (exponent_digits == 0) return false;
  }
  return i == text.size();
}

// Attributes that tell repeated sibling elements apart, in order of preference.
constexpr const char* kKeyAttributes[] = {"id", "NAME", "MARKER"};

// What an encoding declaration other than UTF-8 adds to the message: the
// encoding to convert from (tinyxml2 reads every file as UTF-8).
std::string DeclaredEncodingHint(const tinyxml2::XMLDocument& doc) {
  for (const tinyxml2::XMLNode* node = doc.FirstChild(); node != nullptr;
       node = node->NextSibling()) {
    if (node->ToDeclaration() == nullptr || node->Value() == nullptr) continue;
    const std::string_view declaration = node->Value();
    const std::size_t at = declaration.find("encoding");
    if (at == std::string_view::npos) continue;
    const std::size_t open = declaration.find_first_of("\"'", at);
    const std::size_t close =
        open == std::string_view::npos ? open : declaration.find(declaration[open], open + 1);
    if (close == std::string_view::npos) continue;
    const std::string encoding(declaration.substr(open + 1, close - open - 1));
    std::string lower = encoding;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower == "utf-8" || lower == "utf8") return "";
    return "; the declaration names encoding " + Excerpt(encoding) +
           ": convert the file, e.g. iconv -f " + Excerpt(encoding) + " -t UTF-8";
  }
  return "";
}

// The first name, value, text or comment of the document that is not UTF-8.
// tinyxml2 passes bytes through as they come, so without this check a name
// or number read from them would carry invalid text into reports and JSON.
Status CheckUtf8(const tinyxml2::XMLDocument& doc, const std::string& file_label) {
  const auto problem = [&](std::string_view text) { return InvalidUtf8At(text); };
  const auto message = [&](std::string_view what, std::string_view text, std::size_t at) {
    char byte[8];
    std::snprintf(byte, sizeof(byte), "0x%02X", static_cast<unsigned char>(text[at]));
    return std::string(what) + " is not UTF-8 (byte " + byte + " in '" +
           Excerpt(text.substr(at >= 20 ? at - 20 : 0), 40) +
           "'); expected UTF-8 text (an XML file without an encoding declaration is UTF-8)" +
           DeclaredEncodingHint(doc);
  };
  const tinyxml2::XMLNode* node = doc.FirstChild();
  while (node != nullptr) {
    if (const tinyxml2::XMLElement* element = node->ToElement()) {
      if (const std::size_t at = problem(element->Name()); at != std::string_view::npos)
        return ErrorAt(file_label, element, message("the element name", element->Name(), at));
      for (const tinyxml2::XMLAttribute* a = element->FirstAttribute(); a != nullptr;
           a = a->Next()) {
        if (const std::size_t at = problem(a->Name()); at != std::string_view::npos)
          return ErrorAt(file_label, element, message("an attribute name", a->Name(), at));
        if (const std::size_t at = problem(a->Value()); at != std::string_view::npos)
          return ErrorAt(file_label, element,
                         message(std::string("attribute ") + Excerpt(a->Name()), a->Value(), at));
      }
    } else if (node->Value() != nullptr) {
      const std::string_view text = node->Value();
      if (const std::size_t at = problem(text); at != std::string_view::npos) {
        // The line of the byte itself: the node's first line plus the line
        // breaks before it (tinyxml2 has turned CRLF into LF).
        const int line = node->GetLineNum() +
                         static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
        const tinyxml2::XMLElement* parent =
            node->Parent() != nullptr ? node->Parent()->ToElement() : nullptr;
        const std::string what = node->ToText() != nullptr      ? "text"
                                 : node->ToComment() != nullptr ? "a comment"
                                                                : "a declaration";
        return MakeError(file_label, line, 0,
                         (parent != nullptr ? ElementPath(parent) + ": " : std::string()) +
                             message(what, text, at));
      }
    }
    if (node->FirstChild() != nullptr) {
      node = node->FirstChild();
      continue;
    }
    while (node != nullptr && node->NextSibling() == nullptr) node = node->Parent();
    if (node != nullptr) node = node->NextSibling();
  }
  return Status::Ok();
}

}  // namespace

Expected<std::string> ReadTextFile(const std::filesystem::path& path, const InputLimits& limits) {
  return ReadInputText(path, limits);
}

Status WriteTextFile(const std::filesystem::path& path, std::string_view content) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    return MakeError(path.string(), 0, 0,
                     std::string("cannot open for writing: ") + std::strerror(errno));
  }
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  out.close();
  if (!out) return MakeError(path.string(), 0, 0, "write error");
  return Status::Ok();
}

Status ParseDocument(std::string_view text, const std::string& file_label,
                     tinyxml2::XMLDocument* doc) {
  if (Status s = CheckTextEncoding(text, file_label, "XML"); !s) return s;
  const tinyxml2::XMLError code = doc->Parse(text.data(), text.size());
  if (code != tinyxml2::XML_SUCCESS) {
    std::string what;
    switch (code) {
      case tinyxml2::XML_ERROR_EMPTY_DOCUMENT:
        what = "the document is empty";
        break;
      case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT:
        what = "a closing tag does not match the open element";
        break;
      case tinyxml2::XML_ERROR_PARSING_ELEMENT:
        what = "cannot parse an element";
        break;
      case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE:
        what = "cannot parse an attribute";
        break;
      case tinyxml2::XML_ERROR_PARSING_TEXT:
        what = "cannot parse text";
        break;
      case tinyxml2::XML_ERROR_PARSING:
        what = "unexpected end of the document or an element left open (truncated file?)";
        break;
      default:
        what = doc->ErrorName();
    }
    // tinyxml2 appends details such as "XMLElement name=offset" after the line.
    const std::string full = doc->ErrorStr() != nullptr ? doc->ErrorStr() : "";
    const size_t line_at = full.find("Line number=");
    const size_t detail_at = line_at == std::string::npos ? line_at : full.find(": ", line_at);
    if (detail_at != std::string::npos) what += " (" + Excerpt(full.substr(detail_at + 2), 80) + ")";
    return MakeError(file_label, doc->ErrorLineNum(), 0, "malformed XML: " + what);
  }
  if (doc->RootElement() == nullptr) {
    return MakeError(file_label, 0, 0, "malformed XML: the document has no root element");
  }
  if (const tinyxml2::XMLElement* second = doc->RootElement()->NextSiblingElement()) {
    return MakeError(file_label, second->GetLineNum(), 0,
                     "malformed XML: a second root element <" + Excerpt(second->Name()) +
                         "> after <" + Excerpt(doc->RootElement()->Name()) +
                         ">; expected exactly one root element");
  }
  return CheckUtf8(*doc, file_label);
}

std::string ElementPath(const tinyxml2::XMLElement* element) {
  std::vector<std::string> parts;
  for (const tinyxml2::XMLElement* e = element; e != nullptr;
       e = e->Parent() != nullptr ? e->Parent()->ToElement() : nullptr) {
    std::string part = Excerpt(e->Name());
    for (const char* key : kKeyAttributes) {
      if (const char* value = e->Attribute(key)) {
        part += std::string("[@") + key + "='" + Excerpt(value) + "']";
        break;
      }
    }
    parts.push_back(std::move(part));
  }
  std::string path;
  for (auto it = parts.rbegin(); it != parts.rend(); ++it) path += "/" + *it;
  return path;
}

Error ErrorAt(const std::string& file_label, const tinyxml2::XMLElement* element,
              const std::string& what) {
  return MakeError(file_label, element->GetLineNum(), 0, ElementPath(element) + ": " + what);
}

bool ParseStrictDouble(std::string_view text, double* value) {
  text = Trim(text);
  if (!IsDecimalNumber(text)) return false;
  // from_chars is strtod without the locale (a "," decimal locale must not
  // change what a file means); it does not take a leading '+'.
  if (text.front() == '+') text.remove_prefix(1);
  double parsed = 0.0;
  const auto [end, error] = FromCharsRounded(text.data(), text.data() + text.size(), parsed);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(parsed)) {
    return false;
  }
  *value = parsed;
  return true;
}

bool ParseStrictInt(std::string_view text, int* value) {
  text = Trim(text);
  if (!text.empty() && text.front() == '+') {
    text.remove_prefix(1);
    if (!text.empty() && text.front() == '-') return false;
  }
  if (text.empty()) return false;
  int parsed = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), parsed);
  if (error != std::errc() || end != text.data() + text.size()) return false;
  *value = parsed;
  return true;
}

Expected<const tinyxml2::XMLElement*> OptionalUniqueChild(const std::string& file_label,
                                                          const tinyxml2::XMLElement* parent,
                                                          const char* name) {
  const tinyxml2::XMLElement* first = parent->FirstChildElement(name);
  if (first == nullptr) return static_cast<const tinyxml2::XMLElement*>(nullptr);
  if (const tinyxml2::XMLElement* second = first->NextSiblingElement(name)) {
    return ErrorAt(file_label, second,
                   std::string("duplicate element <") + name + "> (first at line " +
                       std::to_string(first->GetLineNum()) + ")");
  }
  return first;
}

Expected<const tinyxml2::XMLElement*> UniqueChild(const std::string& file_label,
                                                  const tinyxml2::XMLElement* parent,
                                                  const char* name) {
  auto child = OptionalUniqueChild(file_label, parent, name);
  if (!child.ok()) return child;
  if (*child == nullptr) {
    return ErrorAt(file_label, parent, "missing element " + ElementPath(parent) + "/" + name);
  }
  return child;
}

std::vector<const tinyxml2::XMLElement*> Children(const tinyxml2::XMLElement* parent,
                                                  const char* name) {
  std::vector<const tinyxml2::XMLElement*> children;
  for (const tinyxml2::XMLElement* e = parent->FirstChildElement(name); e != nullptr;
       e = e->NextSiblingElement(name)) {
    children.push_back(e);
  }
  return children;
}

Expected<double> ElementNumber(const std::string& file_label, const tinyxml2::XMLElement* element) {
  const char* text = element->GetText();
  double value = 0.0;
  if (text == nullptr || !ParseStrictDouble(text, &value)) {
    return ErrorAt(file_label, element,
                   "expected a number, got '" + Excerpt(text != nullptr ? text : "") + "'");
  }
  return value;
}

Expected<std::string> RequiredAttribute(const std::string& file_label,
                                        const tinyxml2::XMLElement* element, const char* name) {
  const char* value = element->Attribute(name);
  if (value == nullptr) {
    return ErrorAt(file_label, element, std::string("missing attribute ") + name);
  }
  return std::string(value);
}

std::string FormatShortest(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string EscapeXml(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace lifmcr::xml
