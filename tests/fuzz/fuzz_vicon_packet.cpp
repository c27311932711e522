// Vicon Tracker UDP datagram; an accepted packet encodes back to a packet
// that parses equal.

#include "drivers/vicon_tracker_packet.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  Expected<TrackerPacket> packet = ParseTrackerPacket(std::span(data, size));
  if (!packet || packet->skipped_items != 0) return 0;
  Expected<std::vector<std::uint8_t>> bytes = EncodeTrackerPacket(*packet);
  fuzz::Require(bytes.ok(), "an accepted packet encodes");
  Expected<TrackerPacket> again = ParseTrackerPacket(*bytes);
  fuzz::Require(again.ok() && *again == *packet, "encode(parse(x)) parses equal");
  return 0;
}
