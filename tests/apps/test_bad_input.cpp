// Issue 17: bad input never crashes, hangs, exhausts memory or lies. Every
// example of the issue, run through the real `lifmcr` binary: exit code 1,
// a message naming the file and place and what was expected, at most
// kMaxCpuS of CPU time, no hang (kHangS of wall time) and at most kMaxRssMb
// of resident memory (getrusage of the child). The files are written by
// each case into a fresh folder.

#include "replay/bmp.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <functional>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <thread>
#include <tuple>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

// In the Asan build (scripts/test.sh's asan pass) the child is an ASan
// lifmcr: it reserves terabytes of shadow address space, so the RLIMIT_AS
// guard below stopped it before main ("ReserveShadowMemoryRange failed"),
// and its CPU time and resident memory are the sanitizer's (2-3x the CPU, a
// shadow and a quarantine: 217-342 MB for cases that take a few MB), not the
// product's. There ASan's own hard_rss_limit_mb is the guard, the hang limit
// scales as the Asan build's test timeouts do (tests/CMakeLists.txt), and
// every assertion but the CPU and memory bounds holds; the Release suite
// asserts those.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kUnderAsan = true;
#else
constexpr bool kUnderAsan = false;
#endif

constexpr double kMaxCpuS = 1.0;
// Wall: far above kMaxCpuS, only catches a blocked process.
constexpr double kHangS = kUnderAsan ? 80.0 : 20.0;
constexpr long kMaxRssMb = 200;

struct RunResult {
  int exit_code = -1;
  bool hung = false;
  int signal = 0;
  double cpu_s = 0;
  long max_rss_mb = 0;
  std::string out, err;
};

// Runs lifmcr with `args` (no shell: names with newlines pass as they are).
RunResult RunBinary(const std::vector<std::string>& args, const fs::path& scratch) {
  const fs::path out_path = scratch / "stdout", err_path = scratch / "stderr";
  const pid_t pid = fork();
  if (pid == 0) {
    const int out = open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(out, 1);
    dup2(err, 2);
    const int null = open("/dev/null", O_RDONLY);
    dup2(null, 0);
    // A guard for the machine: a regression must fail the test, not swap.
    if (kUnderAsan) {
      const char* options = std::getenv("ASAN_OPTIONS");
      const std::string with_limit =
          std::string(options != nullptr ? options : "") + ":hard_rss_limit_mb=4096";
      setenv("ASAN_OPTIONS", with_limit.c_str(), 1);
    } else {
      rlimit as{4ul << 30, 4ul << 30};
      setrlimit(RLIMIT_AS, &as);
    }
    std::vector<std::string> argv_text = {test::LifmcrBinary().string()};
    argv_text.insert(argv_text.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : argv_text) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  RunResult run;
  int status = 0;
  rusage usage{};
  const auto start = std::chrono::steady_clock::now();
  while (true) {
    const pid_t done = wait4(pid, &status, WNOHANG, &usage);
    if (done == pid) break;
    if (std::chrono::steady_clock::now() - start > std::chrono::duration<double>(kHangS)) {
      kill(pid, SIGKILL);
      wait4(pid, &status, 0, &usage);
      run.hung = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  run.cpu_s = usage.ru_utime.tv_sec + usage.ru_utime.tv_usec / 1e6 + usage.ru_stime.tv_sec +
              usage.ru_stime.tv_usec / 1e6;
  run.max_rss_mb = usage.ru_maxrss / 1024;
  run.out = test::ReadFile(out_path);
  run.err = test::ReadFile(err_path);
  return run;
}

std::string Mla(const std::string& from, const std::string& to) {
  return test::ReplaceFirst(test::ReadSample("raytrix_mla_R42_sc2_klein.xml"), from, to);
}

void Sparse(const fs::path& path, std::uintmax_t bytes, const std::string& head = "") {
  test::WriteFile(path, head);
  fs::resize_file(path, bytes);
}

// A tiny sequence with one camera and frame 0, its white image and MLA file
// in the layout `lifmcr depth` reads: ROOT/S/Q/TypeE_1/..., ROOT/Calibration/...
fs::path TinyDataset(const fs::path& root, int width, int height, const std::string& mla) {
  const fs::path seq = root / "S" / "Q";
  fs::create_directories(seq / "TypeE_1");
  fs::create_directories(root / "Calibration/01_White_Images");
  fs::create_directories(root / "Calibration/02_MLA_Calibration");
  OwnedImage image = OwnedImage::Allocate(width, height, PixelFormat::kMono8);
  std::fill(image.pixels.begin(), image.pixels.end(), 120);
  EXPECT_TRUE(WriteBmp(seq / "TypeE_1/TypeE_1_000000_Raw.bmp", image.View()).ok());
  EXPECT_TRUE(WriteBmp(root / "Calibration/01_White_Images/TypeE_1_00_Raw.bmp", image.View()).ok());
  test::WriteFile(root / "Calibration/02_MLA_Calibration/TypeE_1_MLA.xml", mla);
  return seq;
}

std::string Utf16(const std::string& ascii) {
  std::string out = "\xFF\xFE";
  for (char c : ascii) {
    out += c;
    out += '\0';
  }
  return out;
}

std::string CsvOfSubjects(int subjects) {
  std::string names = ",", columns = "Frame,Sub Frame", units = ",", row = "1,0";
  for (int s = 0; s < subjects; ++s) {
    names += ",o" + std::to_string(s) + ",,,,,";
    columns += ",RX,RY,RZ,TX,TY,TZ";
    units += ",rad,rad,rad,mm,mm,mm";
    row += ",0,0,0,1,2,3";
  }
  return "Objects\n80\n" + names + "\n" + columns + "\n" + units + "\n" + row + "\n";
}

std::string RigWith(const std::string& mla, const std::string& vicon, const std::string& lcm) {
  return "rig: {name: r}\ncameras:\n  - serial: \"1\"\n    name: cam0\n    role: reference\n"
         "    driver: {kind: replay}\n    mla_file: " + mla + "\nvicon:\n" + vicon + "lcm:\n  url: \"" +
         lcm + "\"\n";
}

struct Case {
  std::string name;
  // Writes the input under `dir` and returns the arguments of lifmcr.
  std::function<std::vector<std::string>(const fs::path& dir)> setup;
  std::vector<std::string> expected;  // in stdout + stderr
  int exit_code = 1;
  std::vector<std::string> forbidden = {};  // must not appear in stdout + stderr
};

void AddAnswerCases(std::vector<Case>* cases);

std::vector<Case> Cases() {
  std::vector<Case> cases;
  const auto info_of = [](const std::string& file, const std::string& content) {
    return [file, content](const fs::path& dir) -> std::vector<std::string> {
      test::WriteFile(dir / file, content);
      return {"info", (dir / file).string()};
    };
  };
  const auto mla_case = [&](const std::string& name, const std::string& from,
                            const std::string& to, std::vector<std::string> expected) {
    cases.push_back({name, info_of("m.xml", Mla(from, to)), std::move(expected)});
  };

  // Crash on text it prints.
  cases.push_back({"json_invalid_utf8_in_mla",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     test::WriteFile(dir / "m.xml",
                                     Mla(">34.864704132080<", ">34.86\xFF<"));
                     return {"info", "--json", (dir / "m.xml").string()};
                   },
                   {"/RayCalibData/diameter", "is not UTF-8", "\\\\xFF"}});
  cases.push_back({"json_invalid_utf8_folder_name",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir / "d\xFF", 64, 48,
                                                      Mla("<diameter units=\"pix\">34.864704132080",
                                                          "<diameter units=\"pix\">14.864704132080"));
                     return {"info", "--json", (dir / "d\xFF").string()};
                   },
                   {"d\\\\xFF"}, 0});
  // Unbounded reads.
  for (const std::string ext : {"xml", "vsk", "yaml", "csv", "bmp"}) {
    cases.push_back({"link_to_dev_zero_" + ext,
                     [ext](const fs::path& dir) -> std::vector<std::string> {
                       fs::create_symlink("/dev/zero", dir / ("z." + ext));
                       return {"info", (dir / ("z." + ext)).string()};
                     },
                     {"z." + ext, "is a character device", "expected a regular file"}});
    cases.push_back({"fifo_" + ext,
                     [ext](const fs::path& dir) -> std::vector<std::string> {
                       mkfifo((dir / ("f." + ext)).c_str(), 0600);
                       return {"info", (dir / ("f." + ext)).string()};
                     },
                     {"f." + ext, "is a FIFO (named pipe)", "expected a regular file"}});
  }
  cases.push_back({"link_to_dev_urandom_vsk",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     fs::create_symlink("/dev/urandom", dir / "u.vsk");
                     return {"info", (dir / "u.vsk").string()};
                   },
                   {"u.vsk", "is a character device"}});
  // A frame list is bounded before it is expanded (apps/frame_list.cpp).
  cases.push_back({"frame_list_huge_range",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     return {"synth", "--out", (dir / "out").string(), "--preset", "small",
                             "--frames", "4", "--render-frames", "0-99999999999"};
                   },
                   {"--render-frames", "more than 1000000"},
                   2});  // a bad option value: usage (exit 2), as every option of the CLI
  cases.push_back({"csv_90mb_header_row",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     test::WriteFile(dir / "h.csv", "Objects\n80\n" + std::string(90 << 20, ',') + "\n");
                     return {"info", (dir / "h.csv").string()};
                   },
                   {"h.csv:3:", "more than"}});
  cases.push_back({"xml_128mb",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     Sparse(dir / "big.xml", 128u << 20, "<RayCalibData version=\"1.0\"><x>");
                     return {"info", (dir / "big.xml").string()};
                   },
                   {"big.xml", "128.0 MiB, more than the 1.0 MiB"}});
  // Accepted garbage that crashed later.
  mla_case("mla_diameter_1e300", ">34.864704132080<", ">1e300<",
           {"m.xml:", "/RayCalibData/diameter", "expected 5 .. 500 px, got 1e+300"});
  mla_case("mla_diameter_1e-6", ">34.864704132080<", ">1e-6<",
           {"/RayCalibData/diameter", "expected 5 .. 500 px"});
  mla_case("mla_diameter_0.05", ">34.864704132080<", ">0.05<",
           {"/RayCalibData/diameter", "got 0.05"});
  mla_case("mla_rotation_1e300", ">0.000000000000</rotation>", ">1e300</rotation>",
           {"/RayCalibData/rotation", "expected 0 .. 6.2832"});
  mla_case("mla_offset_1e308", "<x>17.759811322506</x>", "<x>1e308</x>",
           {"/RayCalibData/offset", "expected 0 .. 32768"});
  mla_case("mla_tcp_negative", ">2.180962562561<", ">-5<",
           {"/RayCalibData/tcp", "got -5"});
  mla_case("mla_negative_depth_range", "<min>", "<min>-",
           {"/depth_range", "expected virtual depths 0 .. 1000"});
  {
    std::string million = "0";
    for (int i = 1; i < 1000000; ++i) million += ";0";
    mla_case("mla_million_distortion_parameters", "<parameter count=\"0\">0</parameter>",
             "<parameter count=\"1000000\">" + million + "</parameter>",
             {"m.xml", "more than the 1.0 MiB an MLA calibration XML"});
    std::string thousand = "0";
    for (int i = 1; i < 1000; ++i) thousand += ";0";
    mla_case("mla_thousand_distortion_parameters", "<parameter count=\"0\">0</parameter>",
             "<parameter count=\"1000\">" + thousand + "</parameter>",
             {"/RayCalibData/distortion/parameter", "expected at most 16 distortion parameters"});
  }
  cases.push_back({"mla_two_roots",
                   info_of("m.xml", test::ReadSample("raytrix_mla_R42_sc2_klein.xml") + "\n<Other/>"),
                   {"m.xml:", "a second root element <Other>"}});
  cases.push_back({"depth_with_bad_mla",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, Mla(">34.864704132080<", ">1e-6<"));
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string()};
                   },
                   {"TypeE_1_MLA.xml", "/RayCalibData/diameter", "(MLA file"}});
  cases.push_back({"bmp_100000_square_sparse",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     OwnedImage image = OwnedImage::Allocate(4, 4, PixelFormat::kMono8);
                     EXPECT_TRUE(WriteBmp(dir / "b.bmp", image.View()).ok());
                     std::string bytes = test::ReadFile(dir / "b.bmp");
                     const auto put = [&](std::size_t at, std::uint32_t v) {
                       for (int k = 0; k < 4; ++k) bytes[at + k] = static_cast<char>(v >> (8 * k));
                     };
                     put(18, 100000);
                     put(22, 100000);
                     test::WriteFile(dir / "b.bmp", bytes);
                     fs::resize_file(dir / "b.bmp", 3000000000ull);
                     return {"info", (dir / "b.bmp").string()};
                   },
                   {"b.bmp", "byte 18 (width)", "expected 1 .. 32768 px"}});
  cases.push_back({"depth_with_100000_square_frame",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     const fs::path raw = seq / "TypeE_1/TypeE_1_000000_Raw.bmp";
                     std::string bytes = test::ReadFile(raw);
                     const auto put = [&](std::size_t at, std::uint32_t v) {
                       for (int k = 0; k < 4; ++k) bytes[at + k] = static_cast<char>(v >> (8 * k));
                     };
                     put(18, 100000);
                     put(22, 100000);
                     test::WriteFile(raw, bytes);
                     fs::resize_file(raw, 3000000000ull);
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string()};
                   },
                   {"TypeE_1_000000_Raw.bmp", "byte 18 (width)", "expected 1 .. 32768 px"}});
  // Uncaught exceptions of the intrinsics reader.
  for (const auto& [name, content, expected] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"intrinsics_etc_passwd", "", ""},
           {"intrinsics_cameras_5", "cameras: [5]\n", "/cameras/0: expected a map, got '5'"},
           {"intrinsics_quoted_number",
            "cameras:\n  - serial: \"1\"\n    model: {width_px: \"64\"}\n",
            "/cameras/0/model/width_px: expected an integer"}}) {
    cases.push_back({name,
                     [content = content](const fs::path& dir) -> std::vector<std::string> {
                       const fs::path seq = TinyDataset(dir, 64, 48,
                                                        test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                       const std::string k = content.empty() ? "/etc/passwd" : (dir / "k.yaml").string();
                       if (!content.empty()) test::WriteFile(dir / "k.yaml", content);
                       return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                               (dir / "out").string(), "--intrinsics", k};
                     },
                     {expected.empty() ? "/etc/passwd" : expected}});
  }
  // Quadratic time.
  cases.push_back({"vsk_100k_segments",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     std::string text = "<KinematicModel VERSION=\"3.2\"><Skeleton>";
                     for (int i = 0; i < 100000; ++i) text += "<Segment NAME=\"s" + std::to_string(i) + "\"/>";
                     test::WriteFile(dir / "o.vsk", text + "</Skeleton></KinematicModel>");
                     return {"info", (dir / "o.vsk").string()};
                   },
                   {"o.vsk:1:", "more than 10000 segments"}});
  cases.push_back({"csv_30k_subjects", info_of("s.csv", CsvOfSubjects(30000)),
                   {"s.csv:3:", "more than 60064 fields"}});
  cases.push_back({"vicon_subject_30k_objects",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     test::WriteFile(dir / "s.csv", CsvOfSubjects(30000));
                     return {"vicon", (dir / "s.csv").string(), "--subject", "o29999"};
                   },
                   {"s.csv:3:", "more than 60064 fields"}});
  cases.push_back({"vicon_10k_objects_is_fast",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     test::WriteFile(dir / "s.csv", CsvOfSubjects(10000));
                     return {"vicon", (dir / "s.csv").string(), "--subject", "o9999"};
                   },
                   {"vicon_frame,tx_mm"}, 0});
  // Messages that echo input whole.
  cases.push_back({"mla_900kb_text_node", info_of("m.xml", Mla(">34.864704132080<", ">" + std::string(900000, 'y') + "<")),
                   {"/RayCalibData/diameter", "expected a number, got 'yyyy", "(900000 bytes)"}});
  cases.push_back({"xml_200mb_text_node",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     Sparse(dir / "t.xml", 200u << 20, "<RayCalibData version=\"1.0\"><diameter units=\"pix\">");
                     return {"info", (dir / "t.xml").string()};
                   },
                   {"t.xml", "more than the 1.0 MiB"}});
  cases.push_back({"csv_500mb_line",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     Sparse(dir / "l.csv", 500u << 20, "Objects\n80\n");
                     return {"info", (dir / "l.csv").string()};
                   },
                   {"l.csv", "500.0 MiB, more than the 128.0 MiB"}});
  cases.push_back({"csv_10mb_field",
                   info_of("l.csv", "Objects\n80\n" + std::string(10 << 20, 'n') + "\n"),
                   {"l.csv:3:", "a line longer than 4.0 MiB"}});
  // Within the line bound, the field bound names the field's column.
  cases.push_back({"csv_5kb_field",
                   info_of("f.csv", "Objects\n80\nFrame," + std::string(5000, 'n') + "\n"),
                   {"f.csv:3:7", "field longer than 4096 bytes"}});
  // Messages that mislead.
  cases.push_back({"symlink_loop",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     fs::create_symlink("loop.xml", dir / "loop.xml");
                     return {"info", (dir / "loop.xml").string()};
                   },
                   {"loop.xml", "symbolic link loop"}});
  cases.push_back({"mla_is_a_folder",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     fs::create_directories(dir / "folder.xml");
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string(), "--mla", (dir / "folder.xml").string()};
                   },
                   {"folder.xml", "is a folder, expected a regular file"}});
  cases.push_back({"raw_frame_is_a_fifo",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     fs::remove(seq / "TypeE_1/TypeE_1_000000_Raw.bmp");
                     mkfifo((seq / "TypeE_1/TypeE_1_000000_Raw.bmp").c_str(), 0600);
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string()};
                   },
                   {"TypeE_1_000000_Raw.bmp", "is a FIFO"}});
  cases.push_back({"utf16_mla", info_of("u.xml", Utf16(test::ReadSample("raytrix_mla_R42_sc2_klein.xml"))),
                   {"u.xml", "is UTF-16 text", "iconv"}});
  cases.push_back({"utf16_csv", info_of("u.csv", Utf16("Objects\n80\n")), {"u.csv", "UTF-16"}});
  cases.push_back({"utf16_rig", info_of("u.yaml", Utf16("rig: {name: x}\n")), {"u.yaml", "UTF-16"}});
  cases.push_back({"frame_30_digits",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     return {"depth", seq.string(), "--camera", "1", "--frame",
                             "123456789012345678901234567890", "--out", (dir / "out").string()};
                   },
                   {"--frame: expected a frame number 0 .. 999999999999999999, got '1234"}});
  cases.push_back({"one_by_one_frame",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 1, 1, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string()};
                   },
                   {"white image", "1x1 px, smaller than one micro image"}, 1, {"nan"}});
  // Output injection.
  cases.push_back({"file_name_forging_report_lines",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     test::WriteFile(dir / "S/Q/TypeE_1/x\n    PROBLEM: none\nno problems found", "");
                     return {"info", (dir / "S/Q").string()};
                   },
                   {"x\\n    PROBLEM: none\\nno problems found"}, 0,
                   {"\n    PROBLEM: none\n"}});
  cases.push_back({"text_lists_unrecognised_root_entries",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     TinyDataset(dir, 64, 48, test::ReadSample("raytrix_mla_R42_sc2_klein.xml"));
                     test::WriteFile(dir / "notes.txt", "hello");
                     return {"info", "--quick", dir.string()};
                   },
                   {"not part of the layout:", "notes.txt"}, 0});
  // Error text escaped by every command (config/text_escape.h): a missing
  // file whose name would drive the terminal and forge a line.
  const std::string forged = "x\x1b[31m\nPROBLEM: none";
  const std::string shown = "x\\x1B[31m\\nPROBLEM: none";
  const std::vector<std::string> raw_text = {"\x1b", "\nPROBLEM: none"};
  const auto forged_case = [&](const std::string& name, std::vector<std::string> args, int code) {
    cases.push_back({name,
                     [forged, args](const fs::path& dir) -> std::vector<std::string> {
                       std::vector<std::string> out = args;
                       for (std::string& a : out)
                         if (a == "FORGED") a = (dir / forged).string();
                       return out;
                     },
                     {shown}, code, raw_text});
  };
  forged_case("escaped_grid", {"grid", "FORGED"}, 1);
  forged_case("escaped_synth_config", {"synth", "--config", "FORGED", "--out", "FORGED"}, 2);
  forged_case("escaped_record_rig_usage", {"record", "--rig", "FORGED"}, 2);
  forged_case("escaped_calibrate",
              {"calibrate", "FORGED", "--camera", "1", "--out", "FORGED", "--initial", "FORGED"},
              1);
  forged_case("escaped_register",
              {"register", "FORGED", "--reference-from-ground-truth", "--out", "FORGED"}, 1);
  forged_case("escaped_evaluate", {"evaluate", "FORGED", "--registration", "FORGED", "--out", "FORGED"},
              1);
  forged_case("escaped_replay_usage", {"replay", "FORGED"}, 2);
  forged_case("escaped_depth", {"depth", "FORGED", "--camera", "1", "--frame", "0", "--out", "FORGED"},
              1);
  AddAnswerCases(&cases);
  return cases;
}

// A true answer to every input: inputs that passed as valid,
// or failed with a message about something else, each now a clear answer.
void AddAnswerCases(std::vector<Case>* cases_out) {
  std::vector<Case>& cases = *cases_out;
  const std::string r42 = test::ReadSample("raytrix_mla_R42_sc2_klein.xml");
  const std::string mla_name = "Calibration/02_MLA_Calibration/TypeE_1_MLA.xml";
  // A sequence's MLA file that is not a regular file.
  const std::vector<std::tuple<std::string, std::function<void(const fs::path&)>, std::string>>
      not_files = {
          {"folder", [](const fs::path& p) { fs::create_directories(p); }, "is a folder"},
          {"fifo", [](const fs::path& p) { mkfifo(p.c_str(), 0600); }, "is a FIFO (named pipe)"},
          {"dev_zero", [](const fs::path& p) { fs::create_symlink("/dev/zero", p); },
           "is a character device"}};
  for (const auto& [kind, make, what] : not_files) {
    cases.push_back({"info_sequence_mla_is_a_" + kind,
                     [r42, mla_name, make = make](const fs::path& dir) -> std::vector<std::string> {
                       const fs::path seq = TinyDataset(dir, 64, 48, r42);
                       fs::remove(dir / mla_name);
                       make(dir / mla_name);
                       return {"info", seq.string()};
                     },
                     {"PROBLEM: ", "TypeE_1_MLA.xml: " + what,
                      "expected a regular file holding an MLA calibration XML"},
                     1,
                     {"no TypeE_1_MLA.xml found"}});
  }
  cases.push_back({"info_root_calibration_is_a_file",
                   [r42](const fs::path& dir) -> std::vector<std::string> {
                     TinyDataset(dir, 64, 48, r42);
                     fs::remove_all(dir / "Calibration");
                     test::WriteFile(dir / "Calibration", "notes");
                     return {"info", dir.string()};
                   },
                   {"Calibration: is a file, expected a LiFMCR Calibration folder"}});
  cases.push_back({"info_sequence_calibration_is_a_file",
                   [r42](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, r42);
                     fs::remove_all(dir / "Calibration");
                     test::WriteFile(dir / "Calibration", "notes");
                     return {"info", seq.string()};
                   },
                   {"PROBLEM: ", "Calibration: is a file, expected a LiFMCR Calibration folder"}});
  cases.push_back({"info_frame_is_a_fifo",
                   [r42](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, r42);
                     fs::remove(seq / "TypeE_1/TypeE_1_000000_Raw.bmp");
                     mkfifo((seq / "TypeE_1/TypeE_1_000000_Raw.bmp").c_str(), 0600);
                     return {"info", seq.string()};
                   },
                   {"camera 1: 1 frames", "PROBLEM: ", "TypeE_1_000000_Raw.bmp: is a FIFO"},
                   1,
                   {"files not named as frames"}});
  // VSK and XML that parsed but were not what they claim.
  const auto info_of = [](const std::string& file, const std::string& content) {
    return [file, content](const fs::path& dir) -> std::vector<std::string> {
      test::WriteFile(dir / file, content);
      return {"info", (dir / file).string()};
    };
  };
  cases.push_back({"vsk_without_segments",
                   info_of("o.vsk", "<KinematicModel VERSION=\"3.2\"><Skeleton/></KinematicModel>"),
                   {"o.vsk:1:", "no <Segment>; expected at least one"}});
  cases.push_back({"vsk_empty_segment_name",
                   info_of("o.vsk", "<KinematicModel VERSION=\"3.2\"><Skeleton><Segment NAME=\"\"/>"
                                    "</Skeleton></KinematicModel>"),
                   {"o.vsk:1:", "empty segment NAME"}});
  cases.push_back({"vsk_garbage_version",
                   info_of("o.vsk", test::ReplaceFirst(test::ReadSample("vicon_tracker_object_go2_body.vsk"),
                                                       "VERSION=\"3.2\"", "VERSION=\"garbage!!\"")),
                   {"o.vsk:2:", "VERSION is 'garbage!!'", "expected a version number"}});
  cases.push_back({"xml_latin1_element_text",
                   info_of("m.xml", test::ReplaceFirst(r42, "<function>constant</function>",
                                                       "<function>constant</function><note>caf\xE9</note>")),
                   {"m.xml:23:", "/RayCalibData/distortion/note", "text is not UTF-8 (byte 0xE9"}});
  // Rig files that passed `info`.
  const auto rig_case = [&](const std::string& name, const std::string& mla_file,
                            const std::string& vicon, const std::string& lcm,
                            std::vector<std::string> expected) {
    cases.push_back({name,
                     [r42, mla_file, vicon, lcm](const fs::path& dir) -> std::vector<std::string> {
                       test::WriteFile(dir / "m.xml", r42);
                       test::WriteFile(dir / "garbage.txt", "not an MLA file\n");
                       test::WriteFile(dir / "rig.yaml", RigWith(mla_file, vicon, lcm));
                       return {"info", (dir / "rig.yaml").string()};
                     },
                     std::move(expected)});
  };
  rig_case("rig_lcm_url_nonsense", "m.xml", "  rate_hz: 80\n", "udpm://nonsense!!:abc?bogus=1",
           {"rig.yaml:11:", "/lcm/url", "udpm:// group 'nonsense!!' is not a multicast IPv4 address"});
  rig_case("rig_trigger_rate_tiny", "m.xml", "  rate_hz: 1e-300\n", "memq://",
           {"rig.yaml:9:", "/vicon/rate_hz: expected a number 1 .. 10000 (Hz), got 1e-300"});
  rig_case("rig_trigger_period_minutes", "m.xml", "  rate_hz: 1\n  trigger_divider: 10000\n",
           "memq://", {"/vicon/trigger_divider: gives camera triggers every 10000 s"});
  rig_case("rig_mla_garbage", "garbage.txt", "  rate_hz: 80\n", "memq://",
           {"PROBLEM: ", "garbage.txt", "malformed XML"});
  // The --lcm flags take the rig file's check (config/rig_config.h).
  for (const std::string command : {"replay", "monitor", "demo"}) {
    cases.push_back({"lcm_flag_nonsense_" + command,
                     [command](const fs::path& dir) -> std::vector<std::string> {
                       std::vector<std::string> args = {command, "--lcm", "udpm://nonsense!!:abc"};
                       if (command == "replay") args.push_back(dir.string());
                       return args;
                     },
                     {"--lcm: udpm:// group 'nonsense!!' is not a multicast IPv4 address"},
                     2});
  }
  // Vicon CSV and YAML.
  const std::string block = "Objects\n80\n,,o0,,,,,\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n"
                            ",,rad,rad,rad,mm,mm,mm\n1,0,0,0,0,1,2,3\n";
  cases.push_back({"csv_same_block_twice", info_of("t.csv", block + "\n" + block),
                   {"t.csv:8:1:", "a second block 'Objects' (the first starts at line 1)"}});
  cases.push_back({"csv_underflow_reads_as_zero",
                   info_of("u.csv", test::ReplaceFirst(block, "1,2,3", "1e-400,2,3")),
                   {"block Objects: 80 Hz, 1 frames", "no problems found"}, 0,
                   {"not a finite number", "expected a finite number"}});
  cases.push_back({"yaml_nested_100000_deep",
                   info_of("deep.yaml",
                           "rig: " + std::string(100000, '[') + std::string(100000, ']') + "\n"),
                   {"deep.yaml:1:", "levels deep here, more than the YAML reader takes"}, 1,
                   {"bad file"}});
  // `lifmcr grid` on a white image without --mla: asks for what a white
  // image cannot give, before reading it; given them, writes a valid file.
  cases.push_back({"grid_white_without_mla_asks",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     OwnedImage white = OwnedImage::Allocate(64, 48, PixelFormat::kMono8);
                     EXPECT_TRUE(WriteBmp(dir / "w.bmp", white.View()).ok());
                     return {"grid", (dir / "w.bmp").string(), "--out", (dir / "g.xml").string()};
                   },
                   {"without --mla", "--tcp V and --depth-ranges"}, 2, {"got 0", "not written"}});
  cases.push_back({"grid_white_with_tcp_and_ranges_writes",
                   [](const fs::path& dir) -> std::vector<std::string> {
                     const test::CommandResult synth = test::RunLifmcr(
                         "synth --out " + (dir / "s").string() +
                         " --preset small --frames 1 --cameras 1 --quiet");
                     EXPECT_EQ(synth.exit_code, 0) << synth.err;
                     return {"grid",
                             (dir / "s/Calibration/01_White_Images/TypeE_40398678_00_Raw.bmp").string(),
                             "--out", (dir / "g.xml").string(), "--tcp", "2.2", "--depth-ranges",
                             "1:3,2.8:4,3.8:100"};
                   },
                   {"fitted lattice", "wrote "}, 0});
  // `lifmcr calibrate` checks its options before it processes a frame (a
  // minute of CPU per `medium` frame): a bad value fails at once.
  for (const bool rig : {false, true}) {
    cases.push_back({std::string("calibrate_bad_option_before_frames") + (rig ? "_rig" : ""),
                     [rig](const fs::path& dir) -> std::vector<std::string> {
                       const test::CommandResult synth = test::RunLifmcr(
                           "synth --out " + (dir / "s").string() +
                           " --preset small --frames 1 --cameras 2 --quiet");
                       EXPECT_EQ(synth.exit_code, 0) << synth.err;
                       const fs::path seq = dir / "s/00_Synthetic/Sequence_00";
                       std::vector<std::string> args = {
                           "calibrate", seq.string(), "--initial",
                           (seq / "GroundTruth/cameras.yaml").string(), "--plate-weight", "0",
                           "--out", (dir / "cal").string(), "--camera", "40398678"};
                       if (rig) args.insert(args.end(), {"--rig", "--non-rigid"});
                       return args;
                     },
                     {"plate_weight: expected > 0"}, 2, {"frame 0", "frame 1"}});
  }
  // `lifmcr depth`: values that left no point, and a frame too small.
  cases.push_back({"depth_mla_zero_depth_range",
                   [r42](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(
                         dir, 64, 48, test::ReplaceFirst(r42, "<min>2.799999952316</min>", "<min>4</min>"));
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string()};
                   },
                   {"TypeE_1_MLA.xml:", "lens_type[@id='1']/depth_range",
                    "expected min < max", "got min 4 = max 4"},
                   1,
                   {"no points to write"}});
  cases.push_back({"depth_intrinsics_tiny_b",
                   [r42](const fs::path& dir) -> std::vector<std::string> {
                     const fs::path seq = TinyDataset(dir, 64, 48, r42);
                     test::WriteFile(dir / "k.yaml",
                                     "cameras:\n  - serial: \"1\"\n    model:\n      width_px: 64\n"
                                     "      height_px: 48\n      pixel_size_mm: 0.0055\n"
                                     "      main_focal_length_mm: 25\n      mla_to_main_lens_mm: 24.8\n"
                                     "      mla_to_sensor_mm: 1e-9\n");
                     return {"depth", seq.string(), "--camera", "1", "--frame", "0", "--out",
                             (dir / "out").string(), "--intrinsics", (dir / "k.yaml").string()};
                   },
                   {"mla_to_sensor_mm B = 1e-09 mm", "main_focal_length_mm f_L = 25 mm", "k.yaml"},
                   1,
                   {"no points to write"}});
  for (const bool white : {true, false}) {
    cases.push_back({std::string("depth_one_row_frame_") + (white ? "white" : "no_white"),
                     [r42, white](const fs::path& dir) -> std::vector<std::string> {
                       const fs::path seq = TinyDataset(dir, 64, 1, r42);
                       std::vector<std::string> args = {"depth", seq.string(), "--camera", "1",
                                                        "--frame", "0", "--out",
                                                        (dir / "out").string()};
                       if (!white) args.push_back("--no-white");
                       return args;
                     },
                     {white ? "white image: 64x1 px, smaller than one micro image"
                            : "raw frame: 64x1 px, smaller than one micro image",
                      "diameter 35 px in the MLA file"},
                     1,
                     {"float map size"}});
  }
}

class BadInput : public testing::TestWithParam<Case> {};

TEST_P(BadInput, IsAClearQuickBoundedError) {
  const Case& c = GetParam();
  {
    test::TempDir dir;
    fs::create_directories(dir / "in");
    const std::vector<std::string> args = c.setup(dir / "in");
    const RunResult run = RunBinary(args, dir.path());
    RecordProperty("cpu_s", std::to_string(run.cpu_s));
    RecordProperty("max_rss_mb", std::to_string(run.max_rss_mb));
    const std::string all = run.out + run.err;
    EXPECT_FALSE(run.hung) << "hung";
    EXPECT_EQ(run.signal, 0) << "killed by signal " << run.signal << "\n" << all.substr(0, 2000);
    EXPECT_EQ(run.exit_code, c.exit_code) << all.substr(0, 2000);
    if (!kUnderAsan) {
      EXPECT_LE(run.cpu_s, kMaxCpuS);
      EXPECT_LE(run.max_rss_mb, kMaxRssMb);
    }
    for (const std::string& part : c.expected)
      EXPECT_NE(all.find(part), std::string::npos) << "lacks '" << part << "' in\n" << all.substr(0, 2000);
    for (const std::string& part : c.forbidden)
      EXPECT_EQ(all.find(part), std::string::npos) << "has '" << part << "' in\n" << all.substr(0, 2000);
    // Messages quote at most an excerpt of the input.
    EXPECT_LT(run.err.size(), 4096u) << run.err.substr(0, 2000);
    if (std::find(args.begin(), args.end(), "--json") != args.end()) {
      EXPECT_TRUE(nlohmann::json::accept(run.out)) << run.out.substr(0, 2000);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(UserInput, BadInput, testing::ValuesIn(Cases()),
                         [](const testing::TestParamInfo<Case>& info) {
                           std::string name = info.param.name;
                           for (char& ch : name)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return name;
                         });

}  // namespace
}  // namespace lifmcr
