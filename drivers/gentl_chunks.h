#pragma once
// Chunk data of GenTL buffers: values the camera appends to each frame
// (ChunkTimestamp, ChunkFrameID, ...), found where the device's GenICam XML
// says: the Integer feature's register (pValue) lives at an address of a
// chunk port, a Port whose ChunkID names the chunk; DSGetBufferChunkData
// gives where each chunk of a buffer is. This reads the value straight from
// the pooled buffer, without a chunk adapter or a copy.
//
// Includes <arv.h>: for drivers/*.cpp only.

#include "drivers/gentl_api.h"

#include <arv.h>

#include <cstdint>
#include <optional>
#include <vector>

namespace lifmcr {

// Where a chunk feature's value sits: `length` bytes at `offset` from the
// start of the chunk `chunk_id`, in the register's byte order.
struct ChunkField {
  std::uint64_t chunk_id = 0;
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  bool little_endian = true;
};

// The field behind Integer feature `feature` (pValue -> IntReg -> pPort with a
// ChunkID), or nullopt when the device has no such chunk feature.
std::optional<ChunkField> ResolveChunkField(ArvDevice* device, const char* feature);

// The field's value in a buffer whose chunks are `chunks` (offsets from
// `base`, `size` bytes valid), or nullopt when the chunk is absent or short.
std::optional<std::uint64_t> ReadChunkField(const ChunkField& field, const std::uint8_t* base,
                                            std::size_t size,
                                            const std::vector<gentl::SINGLE_CHUNK_DATA>& chunks);

}  // namespace lifmcr
