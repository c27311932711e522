// Layout discovery and `lifmcr info` on a folder tree generated from the
// input: folders, small files, FIFOs, symlink loops and dangling links
// named after the LiFMCR layout (and names with control characters and
// invalid UTF-8). The whole report, as text and as JSON, must render.

#include "apps/info_report.h"
#include "replay/sequence.h"
#include "tests/fuzz/fuzz_util.h"

#include <fcntl.h>
#include <filesystem>
#include <sys/stat.h>
#include <vector>

namespace {

namespace fs = std::filesystem;

const char* const kNames[] = {
    "Calibration", "01_White_Images", "02_MLA_Calibration", "03_Vicon", "Object.vsk", "Vicon",
    "sequence_01.csv", "TypeE_40398673", "TypeE_40398678", "TypeE_40398673_000001_Raw.bmp",
    "TypeE_40398673_7_Raw.bmp", "TypeE_40398673_999999999999999999_Raw.bmp",
    "TypeE_40398673_00_Raw.bmp", "TypeE_40398673_MLA.xml", "GroundTruth", "01_Scene", "Seq_00",
    "x\n    PROBLEM: none", "bad\xff\xfe", "TypeE_4039867\x1b[31m", "rig.yaml", "a.csv"};
constexpr std::size_t kNameCount = sizeof(kNames) / sizeof(kNames[0]);

fs::path Root() {
  static const fs::path root = [] {
    const char* tmp = std::getenv("TMPDIR");
    fs::path base = fs::path(tmp != nullptr ? tmp : "/tmp") /
                    ("lifmcr_fuzz_tree_" + std::to_string(::getpid()));
    return base;
  }();
  return root;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  const fs::path root = Root();
  std::error_code ec;
  fs::remove_all(root, ec);
  fs::create_directories(root / "data", ec);
  fuzz::Require(!ec, "create the fuzz root");
  std::vector<fs::path> stack = {root / "data"};
  std::size_t entries = 0;
  for (std::size_t i = 0; i + 1 < size && entries < 64; i += 2, ++entries) {
    const std::uint8_t op = data[i] % 8;
    const fs::path at = stack.back() / kNames[data[i + 1] % kNameCount];
    switch (op) {
      case 0:  // a folder, entered
        if (stack.size() < 7 && fs::create_directory(at, ec)) stack.push_back(at);
        break;
      case 1:  // a small file holding the next bytes
      case 2: {
        const std::size_t n = std::min<std::size_t>(data[i + 1] % 32, size - i - 2);
        // Never blocks: a FIFO made earlier under this name has no reader.
        const int fd = ::open(at.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_NONBLOCK | O_NOFOLLOW, 0644);
        if (fd >= 0) {
          if (::write(fd, data + i + 2, n) < 0) {
          }
          ::close(fd);
        }
        break;
      }
      case 3:  // back up
        if (stack.size() > 1) stack.pop_back();
        break;
      case 4:  // a link to its own folder (a loop when followed down)
        fs::create_symlink(".", at, ec);
        break;
      case 5:  // a FIFO where a file belongs
        ::mkfifo(at.c_str(), 0600);
        break;
      case 6:  // a dangling link
        fs::create_symlink("nowhere", at, ec);
        break;
      default:  // a link to itself (ELOOP)
        fs::create_symlink(at.filename(), at, ec);
    }
  }
  const fs::path top = root / "data";
  for (const fs::path& path : {top, stack.back()}) {
    apps::InfoOptions options;
    Expected<nlohmann::json> report = apps::DescribePath(path, options);
    if (report) {
      (void)apps::FormatInfoText(*report);
      (void)report->dump(2);
    }
    if (Expected<SequenceLayout> sequence = DiscoverSequence(path)) {
      if (Expected<SequenceReader> reader = SequenceReader::Create(*sequence, {})) {
        for (int k = 0; k < 100 && reader->Next(); ++k) {
        }
      }
    }
    (void)DiscoverDataset(path);
    (void)DiscoverScene(path);
    (void)DiscoverCalibration(path);
  }
  fs::remove_all(root, ec);
  return 0;
}
