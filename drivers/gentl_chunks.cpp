#include "drivers/gentl_chunks.h"

#include <cstdlib>
#include <cstring>
#include <string>

namespace lifmcr {
namespace {

// The first child element named `name` of `node`, as a property node.
ArvGcPropertyNode* Property(ArvGcNode* node, const char* name) {
  for (ArvDomNode* child = arv_dom_node_get_first_child(ARV_DOM_NODE(node)); child != nullptr;
       child = arv_dom_node_get_next_sibling(child)) {
    const char* child_name = arv_dom_node_get_node_name(child);
    if (child_name != nullptr && std::strcmp(child_name, name) == 0 &&
        ARV_IS_GC_PROPERTY_NODE(child))
      return ARV_GC_PROPERTY_NODE(child);
  }
  return nullptr;
}

// The element's own text (for a pValue or pPort: the name it points to, not
// the pointed node's value, which arv_gc_property_node_get_string returns).
std::string PropertyText(ArvGcNode* node, const char* name) {
  ArvGcPropertyNode* property = Property(node, name);
  if (property == nullptr) return {};
  std::string text;
  for (ArvDomNode* child = arv_dom_node_get_first_child(ARV_DOM_NODE(property)); child != nullptr;
       child = arv_dom_node_get_next_sibling(child)) {
    const char* value = arv_dom_node_get_node_value(child);
    if (value != nullptr) text += value;
  }
  const auto first = text.find_first_not_of(" \t\r\n");
  const auto last = text.find_last_not_of(" \t\r\n");
  return first == std::string::npos ? std::string() : text.substr(first, last - first + 1);
}

}  // namespace

std::optional<ChunkField> ResolveChunkField(ArvDevice* device, const char* feature) {
  ArvGc* genicam = arv_device_get_genicam(device);
  if (genicam == nullptr) return std::nullopt;
  ArvGcNode* node = arv_gc_get_node(genicam, feature);
  if (node == nullptr) return std::nullopt;
  // An Integer points at its register; an IntReg is the register itself.
  if (!ARV_IS_GC_REGISTER(node)) {
    const std::string value = PropertyText(node, "pValue");
    node = value.empty() ? nullptr : arv_gc_get_node(genicam, value.c_str());
  }
  if (node == nullptr || !ARV_IS_GC_REGISTER(node)) return std::nullopt;
  const std::string port_name = PropertyText(node, "pPort");
  ArvGcNode* port = port_name.empty() ? nullptr : arv_gc_get_node(genicam, port_name.c_str());
  if (port == nullptr) return std::nullopt;
  const std::string chunk_id = PropertyText(port, "ChunkID");
  if (chunk_id.empty()) return std::nullopt;  // a device register, not a chunk
  ChunkField field;
  char* end = nullptr;
  field.chunk_id = std::strtoull(chunk_id.c_str(), &end, 16);  // ChunkID is hexadecimal
  if (end == chunk_id.c_str()) return std::nullopt;
  GError* error = nullptr;
  field.offset = arv_gc_register_get_address(ARV_GC_REGISTER(node), &error);
  if (error == nullptr) field.length = arv_gc_register_get_length(ARV_GC_REGISTER(node), &error);
  if (error != nullptr) {
    g_error_free(error);
    return std::nullopt;
  }
  if (field.length == 0 || field.length > 8) return std::nullopt;
  ArvGcPropertyNode* endianness = Property(node, "Endianess");
  field.little_endian = endianness == nullptr ||
                        arv_gc_property_node_get_endianness(endianness, G_LITTLE_ENDIAN) ==
                            G_LITTLE_ENDIAN;
  return field;
}

std::optional<std::uint64_t> ReadChunkField(const ChunkField& field, const std::uint8_t* base,
                                            std::size_t size,
                                            const std::vector<gentl::SINGLE_CHUNK_DATA>& chunks) {
  for (const gentl::SINGLE_CHUNK_DATA& chunk : chunks) {
    if (chunk.ChunkID != field.chunk_id || chunk.ChunkOffset < 0) continue;
    const std::size_t start = static_cast<std::size_t>(chunk.ChunkOffset) + field.offset;
    if (field.offset + field.length > chunk.ChunkLength || start + field.length > size)
      return std::nullopt;
    std::uint64_t value = 0;
    for (std::uint64_t i = 0; i < field.length; ++i) {
      const std::uint64_t byte = base[start + (field.little_endian ? i : field.length - 1 - i)];
      value |= byte << (8 * i);
    }
    return value;
  }
  return std::nullopt;
}

}  // namespace lifmcr
