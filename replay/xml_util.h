#pragma once
// Helpers shared by the XML readers and writers of lifmcr_replay (MLA
// calibration XML, Vicon VSK). INTERNAL to lifmcr_replay: include it only from
// replay/*.cpp. tinyxml2 is linked PRIVATE to lifmcr_replay, so this header
// only forward-declares its types and never includes <tinyxml2.h>.
//
// Every error message produced here has the shape
//   "<file>:<line>: <element path>: <what>"
// (MakeError with the line of the element at fault), for example
//   "R42.xml:14: /RayCalibData/lens_base_y: missing element /RayCalibData/lens_base_y/y".

#include "config/error.h"
#include "config/input_file.h"

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

// Propagation of errors inside the readers: `lhs = *expr` or return its error.
#define LIFMCR_XML_CONCAT_INNER(a, b) a##b
#define LIFMCR_XML_CONCAT(a, b) LIFMCR_XML_CONCAT_INNER(a, b)
#define LIFMCR_XML_ASSIGN_OR_RETURN(lhs, expr)               \
  auto LIFMCR_XML_CONCAT(xml_result_, __LINE__) = (expr);    \
  if (!LIFMCR_XML_CONCAT(xml_result_, __LINE__).ok())        \
    return LIFMCR_XML_CONCAT(xml_result_, __LINE__).error(); \
  lhs = std::move(*LIFMCR_XML_CONCAT(xml_result_, __LINE__))
#define LIFMCR_XML_RETURN_IF_ERROR(expr)               \
  do {                                                 \
    const ::lifmcr::Status xml_status_ = (expr);       \
    if (!xml_status_.ok()) return xml_status_.error(); \
  } while (false)

namespace tinyxml2 {
class XMLDocument;
class XMLElement;
}  // namespace tinyxml2

namespace lifmcr::xml {

// Reads a whole file through ReadInputText (config/input_file.h): a regular
// file of at most limits.max_bytes, UTF-8 text.
Expected<std::string> ReadTextFile(const std::filesystem::path& path, const InputLimits& limits);
// Writes `content` as bytes, replacing the file. Error names the path.
Status WriteTextFile(const std::filesystem::path& path, std::string_view content);

// Parses `text` into `doc`. Malformed or truncated XML gives
// "<file_label>:<line>: malformed XML: <tinyxml2's description>"; so does a
// second root element (tinyxml2 would accept it and lifmcr would silently
// read only the first), and UTF-16/32 text or NUL bytes. A name, attribute
// value, text or comment that is not UTF-8 is an error at its element and
// line, naming the byte (and, when the declaration names another encoding,
// that encoding to convert from).
Status ParseDocument(std::string_view text, const std::string& file_label,
                     tinyxml2::XMLDocument* doc);

// "/Root/child/leaf" from the document root down to `element`. An element
// with an `id`, `NAME` or `MARKER` attribute is qualified so that repeated
// siblings can be told apart: "/RayCalibData/lens_type[@id='1']/offset".
std::string ElementPath(const tinyxml2::XMLElement* element);

// MakeError(file_label, line of element, 0, ElementPath(element) + ": " + what).
Error ErrorAt(const std::string& file_label, const tinyxml2::XMLElement* element,
              const std::string& what);

// Strict decimal number: optional surrounding whitespace, then what strtod
// reads in the "C" locale ("17.759811322506", "2.54233651836e-005", "1",
// "-8.7e-8"), and nothing else: no trailing junk, no hex, no inf/nan, no
// empty text. Returns false when `text` is not such a number.
bool ParseStrictDouble(std::string_view text, double* value);
// Strict base-10 integer (optional sign, digits, surrounding whitespace).
bool ParseStrictInt(std::string_view text, int* value);

// The only child of `parent` named `name`. Errors: missing ("missing element
// <path>/<name>") or repeated ("duplicate element <name> (first at line N)").
Expected<const tinyxml2::XMLElement*> UniqueChild(const std::string& file_label,
                                                  const tinyxml2::XMLElement* parent,
                                                  const char* name);
// As UniqueChild but a missing child is not an error (returns nullptr).
Expected<const tinyxml2::XMLElement*> OptionalUniqueChild(const std::string& file_label,
                                                          const tinyxml2::XMLElement* parent,
                                                          const char* name);
// All children of `parent` named `name`, in document order.
std::vector<const tinyxml2::XMLElement*> Children(const tinyxml2::XMLElement* parent,
                                                  const char* name);

// The element's text as a strict number; error "expected a number, got '…'".
Expected<double> ElementNumber(const std::string& file_label, const tinyxml2::XMLElement* element);

// The value of a required attribute; error "missing attribute NAME".
Expected<std::string> RequiredAttribute(const std::string& file_label,
                                        const tinyxml2::XMLElement* element, const char* name);

// Shortest decimal text that reads back to exactly `value` (std::to_chars).
std::string FormatShortest(double value);

// `text` with &, <, >, " and ' replaced by entities, for attribute values and text.
std::string EscapeXml(std::string_view text);

}  // namespace lifmcr::xml
