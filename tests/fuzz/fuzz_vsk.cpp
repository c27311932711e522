// Vicon VSK, then the per-subject queries `lifmcr info` makes.

#include "replay/vsk.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  Expected<Vsk> vsk = ParseVsk(fuzz::Text(data, size), "fuzz.vsk");
  if (!vsk) return 0;
  std::size_t total = 0;
  for (const auto& [subject, markers] : VskMarkersBySubject(*vsk)) total += markers.size();
  fuzz::Require(total <= vsk->markers.size(), "each marker belongs to at most one subject");
  const std::vector<std::string> subjects = VskSubjects(*vsk);
  for (std::size_t i = 0; i < subjects.size() && i < 4; ++i) {
    fuzz::Require(VskMarkersOfSubject(*vsk, subjects[i]).size() <= vsk->markers.size(),
                  "markers of a subject");
    (void)VskMarkerCentroidMm(*vsk, subjects[i]);
  }
  if (Expected<std::string> text = FormatVsk(*vsk)) (void)ParseVsk(*text, "again.vsk");
  return 0;
}
