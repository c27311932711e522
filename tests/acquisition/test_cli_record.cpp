// `lifmcr record` as a user runs it: Aravis's in-process fake camera
// ("Fake_1") through the real driver, the Vicon stream from the test sender
// on loopback, stopped by --duration, SIGTERM or kill -9; the recording is
// read back through the dataset layer and `lifmcr info`.
#include "acquisition/memory_camera.h"
#include "acquisition/recorder.h"
#include "config/rig_config.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"
#include "tests/acquisition/rig_fixture.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <algorithm>
#include <chrono>
#include <csignal>
#include <fcntl.h>
#include <filesystem>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

// A UDP port free right now on 127.0.0.1 (the kernel's choice).
int FreeUdpPort() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = 0;
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address));
  socklen_t length = sizeof(address);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  ::close(fd);
  return ntohs(address.sin_port);
}

fs::path WriteFakeRig(const fs::path& dir, int vicon_port) {
  const fs::path mla = fs::path(LIFMCR_SOURCE_DIR) /
                       "config/examples/Calibration/02_MLA_Calibration/TypeE_40398678_MLA.xml";
  const fs::path rig = dir / "rig.yaml";
  test::WriteFile(rig,
                  "rig:\n  name: fake_one\n"
                  "cameras:\n"
                  "  - serial: FAKE1\n    name: cam0\n    role: reference\n"
                  "    driver: {kind: aravis, address: Fake_1}\n"
                  "    mla_file: " +
                      mla.string() +
                      "\n"
                      "    trigger: {mode: software}\n    exposure_us: 2000\n"
                      "    pixel_format: Mono8\n"
                      "    roi: {x: 0, y: 0, width: 256, height: 128}\n"
                      "    vicon_object: cam0\n"
                      "vicon:\n  source: udp\n"
                      "  udp: {address: 127.0.0.1, port: " +
                      std::to_string(vicon_port) +
                      "}\n"
                      "  rate_hz: 80\n  trigger_divider: 8\n"
                      "recorder:\n  queue_frames: 8\n");
  return rig;
}

// `lifmcr record` in a child process, stdout and stderr to files.
class RecordProcess {
 public:
  RecordProcess(const std::string& args, const fs::path& out_file, const fs::path& err_file) {
    pid_ = fork();
    if (pid_ == 0) {
      const int out = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int err = ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(out, 1);
      ::dup2(err, 2);
      const std::string command = "exec '" + test::LifmcrBinary().string() + "' record " + args;
      ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~RecordProcess() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  void Signal(int signal_number) { ::kill(pid_, signal_number); }
  // The wait status, or -1 when it did not end within `timeout`.
  int Wait(milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        reaped_ = true;
        return status;
      }
      std::this_thread::sleep_for(milliseconds(20));
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
};

struct Recording {
  test::TempDir dir;
  int port = FreeUdpPort();
  fs::path rig_path = WriteFakeRig(dir.path(), port);
  fs::path out = dir / "out";
  fs::path seq = out / "00_Recording" / "seq";
  fs::path stdout_file = dir / "stdout.txt";
  fs::path stderr_file = dir / "stderr.txt";
  std::string Args(const std::string& extra) const {
    return "--rig '" + rig_path.string() + "' --out '" + out.string() + "' " + extra;
  }
  std::string Log() const {
    return "stdout:\n" + test::ReadFile(stdout_file) + "\nstderr:\n" + test::ReadFile(stderr_file);
  }
};

TEST(RecordCli, SigtermStopsCleanlyWithACompleteCsv) {
  Recording r;
  auto rig = LoadRigConfig(r.rig_path);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  RecordProcess process(r.Args(""), r.stdout_file, r.stderr_file);
  test::ViconStreamer streamer(*rig, r.port, 80.0);
  ASSERT_TRUE(streamer.ok());
  // Stopped once the recording is under way (more than 80 Vicon lines and
  // more than 5 frames on disk), not after a fixed time: on a loaded host
  // the binary may take seconds to start.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  for (;;) {
    const std::string text = test::ReadFile(layout::ViconCsvPath(r.seq, 1));
    const auto lines = std::count(text.begin(), text.end(), '\n');
    auto partial = DiscoverSequence(r.seq);
    const std::size_t frames =
        partial.ok() && !partial->cameras.empty() ? partial->cameras[0].frames.size() : 0;
    if ((lines > 90 && frames > 5) || std::chrono::steady_clock::now() > give_up) break;
    std::this_thread::sleep_for(milliseconds(50));
  }
  process.Signal(SIGTERM);
  const int status = process.Wait(milliseconds(10000));
  ASSERT_NE(status, -1) << "did not stop on SIGTERM\n" << r.Log();
  ASSERT_TRUE(WIFEXITED(status)) << r.Log();
  EXPECT_LE(WEXITSTATUS(status), 1) << r.Log();
  const std::string out = test::ReadFile(r.stdout_file);
  EXPECT_NE(out.find("stopped by: SIGTERM"), std::string::npos) << r.Log();
  EXPECT_NE(out.find("camera FAKE1: recorded"), std::string::npos) << r.Log();

  auto sequence = DiscoverSequence(r.seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message << r.Log();
  ASSERT_EQ(sequence->cameras.size(), 1u);
  EXPECT_GT(sequence->cameras[0].frames.size(), 5u) << r.Log();
  for (const std::string& file : sequence->cameras[0].frame_files) {
    auto header = ReadBmpHeader(sequence->cameras[0].dir / file);
    ASSERT_TRUE(header.ok()) << header.error().message;
    EXPECT_EQ(header->width, 256);
    EXPECT_EQ(header->height, 128);
  }
  const std::string csv_text = test::ReadFile(layout::ViconCsvPath(r.seq, 1));
  ASSERT_FALSE(csv_text.empty()) << r.Log();
  EXPECT_EQ(csv_text.back(), '\n');
  auto csv = ReadViconCsv(layout::ViconCsvPath(r.seq, 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_GT(csv->blocks.at(0).num_rows(), 80u);

  const auto info = test::RunLifmcr("info '" + r.out.string() + "'");
  EXPECT_EQ(info.exit_code, 0) << info.out << info.err;
}

TEST(RecordCli, KillNineLeavesEverythingButTheLastFileReadable) {
  Recording r;
  auto rig = LoadRigConfig(r.rig_path);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  RecordProcess process(r.Args(""), r.stdout_file, r.stderr_file);
  test::ViconStreamer streamer(*rig, r.port, 80.0);
  // Killed once the recording is under way (more than 40 Vicon lines and
  // some frames on disk), not after a fixed time: on a loaded host the
  // binary may take a second to start.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  for (;;) {
    const std::string text = test::ReadFile(layout::ViconCsvPath(r.seq, 1));
    const auto lines = std::count(text.begin(), text.end(), '\n');
    if (lines > 60 || std::chrono::steady_clock::now() > give_up) break;
    std::this_thread::sleep_for(milliseconds(50));
  }
  process.Signal(SIGKILL);
  ASSERT_NE(process.Wait(milliseconds(5000)), -1);
  auto sequence = DiscoverSequence(r.seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message << r.Log();
  int unreadable = 0;
  for (const std::string& file : sequence->cameras.at(0).frame_files)
    if (!ReadBmp(sequence->cameras[0].dir / file).ok()) ++unreadable;
  EXPECT_GT(sequence->cameras[0].frames.size(), 5u);
  EXPECT_LE(unreadable, 1);  // one writer thread: at most the file it was writing
  auto csv = ReadViconCsv(layout::ViconCsvPath(r.seq, 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_GT(csv->blocks.at(0).num_rows(), 40u);
}

TEST(RecordCli, DurationEndsTheRecordingAndExitCodeSaysNothingWasLost) {
  Recording r;
  auto rig = LoadRigConfig(r.rig_path);
  ASSERT_TRUE(rig.ok());
  RecordProcess process(r.Args("--duration 1.5"), r.stdout_file, r.stderr_file);
  test::ViconStreamer streamer(*rig, r.port, 80.0);
  const int status = process.Wait(milliseconds(10000));
  ASSERT_NE(status, -1) << r.Log();
  ASSERT_TRUE(WIFEXITED(status));
  const std::string out = test::ReadFile(r.stdout_file);
  EXPECT_NE(out.find("stopped by: duration reached"), std::string::npos) << r.Log();
  // The exit code is the report's verdict.
  const bool lost = out.find("result: something was lost") != std::string::npos;
  EXPECT_EQ(WEXITSTATUS(status), lost ? 1 : 0) << r.Log();
  // One status line per second when stderr is not a terminal.
  EXPECT_NE(test::ReadFile(r.stderr_file).find("fps"), std::string::npos) << r.Log();

  // Recording into the same sequence again is refused and touches nothing.
  const auto again = test::RunLifmcr("record " + r.Args("--duration 1"));
  EXPECT_EQ(again.exit_code, 3) << again.err;
  EXPECT_NE(again.err.find("not empty"), std::string::npos) << again.err;
}

TEST(RecordCli, UsageErrors) {
  const auto help = test::RunLifmcr("record --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* word : {"--rig", "--out", "--duration", "--scene", "--sequence", "SIGTERM",
                           "Exit code", "sequence_01.csv"})
    EXPECT_NE(help.out.find(word), std::string::npos) << word;
  test::TempDir dir;
  test::WriteFile(dir / "bad.yaml", "rig: {name: x}\ncameras: []\n");
  const auto bad = test::RunLifmcr("record --rig '" + (dir / "bad.yaml").string() + "' --out '" +
                                   (dir / "out").string() + "'");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("bad.yaml"), std::string::npos) << bad.err;

  // The registration options (shared with replay, apps/registration_args.h)
  // are refused where they would be ignored, before the rig file is read.
  const std::string rig = " --rig '" + (dir / "bad.yaml").string() + "'";
  const auto csv_alone = test::RunLifmcr("record" + rig + " --publish --extrinsics-csv x.csv");
  EXPECT_EQ(csv_alone.exit_code, 2);
  EXPECT_NE(csv_alone.err.find("--extrinsics-csv needs --reference"), std::string::npos)
      << csv_alone.err;
  const auto unpublished =
      test::RunLifmcr("record" + rig + " --reference '" + dir.path().string() + "'");
  EXPECT_EQ(unpublished.exit_code, 2);
  EXPECT_NE(unpublished.err.find("--reference needs --publish"), std::string::npos)
      << unpublished.err;
}

// A recording replayed through the replay driver and recorded again comes
// out byte for byte the same, its dropped frame included (and reported).
TEST(RecordCli, ReplayedSequenceRecordsIdenticalFilesAndReportsItsGap) {
  test::TempDir dir;
  RigConfig rig = test::TwoCameraRig();
  rig.vicon.source = ViconSourceKind::kNone;
  rig.vicon.rate_hz = 400;  // 50 Hz triggers: the replay takes 0.4 s
  rig.vicon.udp.port = 51001;
  for (CameraConfig& camera : rig.cameras) camera.trigger.mode = TriggerMode::kHardware;
  RecorderOptions options;
  options.root_dir = dir / "a";
  {
    auto recorder = Recorder::Create(rig, options);
    ASSERT_TRUE(recorder.ok()) << recorder.error().message;
    for (int c = 0; c < 2; ++c) {
      MemoryCameraOptions camera_options;
      camera_options.serial = rig.cameras[c].serial;
      camera_options.width = 40 + c;
      camera_options.height = 30;
      camera_options.pool_frames = 32;
      camera_options.format = c == 0 ? PixelFormat::kMono8 : PixelFormat::kBgr8;
      MemoryCamera camera(camera_options);
      ASSERT_TRUE(camera.Open().ok() && camera.Start().ok());
      for (int f = 0; f < 20; ++f) {
        ASSERT_TRUE(camera.SoftwareTrigger().ok());
        auto frame = camera.NextFrame(milliseconds(1000));
        ASSERT_TRUE(frame.ok() && frame->has_value());
        if (c == 1 && f == 7) continue;  // camera B lost frame 7
        EXPECT_TRUE((*recorder)->SubmitFrame(c, f, std::move(**frame)));
        std::this_thread::sleep_for(milliseconds(2));  // no queue-full drop
      }
    }
    (*recorder)->Stop();
  }
  const fs::path original = dir / "a" / "00_Recording" / "seq";
  const fs::path rig_path = dir / "replay_rig.yaml";
  test::WriteFile(rig_path, FormatRigConfig(rig));
  const fs::path log = dir / "record.log";
  const auto result = test::RunLifmcr(
      "--log-level info --log-file '" + log.string() + "' record --rig '" + rig_path.string() +
      "' --replay '" + original.string() + "' --out '" + (dir / "b").string() + "' --duration 20");
  EXPECT_EQ(result.exit_code, 1) << result.out << result.err;  // the gap is a loss
  // The operator's log: the configuration in force, and the loss with its cause.
  const std::string logged = test::ReadFile(log);
  EXPECT_NE(logged.find("rig: 2 camera(s)"), std::string::npos) << logged;
  EXPECT_NE(logged.find("record: camera MEMB: lost 1 [incomplete 0, missing ids 1"),
            std::string::npos)
      << logged;
  EXPECT_EQ(logged.find("record: camera MEMA"), std::string::npos) << logged;
  EXPECT_NE(result.out.find("stopped by: end of the replayed sequence"), std::string::npos)
      << result.out << result.err;
  EXPECT_NE(result.out.find("missing ids 1"), std::string::npos) << result.out;
  const fs::path copy = dir / "b" / "00_Recording" / "seq";
  for (const char* serial : {"MEMA", "MEMB"}) {
    for (int f = 0; f < 20; ++f) {
      const fs::path a = layout::RawFramePath(original, serial, f);
      const fs::path b = layout::RawFramePath(copy, serial, f);
      ASSERT_EQ(fs::exists(a), fs::exists(b)) << b;
      if (fs::exists(a)) {
        EXPECT_EQ(test::ReadFile(a), test::ReadFile(b)) << b;
      }
    }
  }
  EXPECT_FALSE(fs::exists(layout::RawFramePath(copy, "MEMB", 7)));
}

// The writer puts the header block last, so a frame cut off by a crash
// (pixels on disk, header not yet) is a broken BMP that `lifmcr info` names,
// while every other frame of the sequence reads.
TEST(RecordCli, InfoNamesAFrameCutOffBeforeItsHeader) {
  test::TempDir dir;
  RigConfig rig = test::TwoCameraRig();
  rig.cameras.resize(1);
  rig.vicon.source = ViconSourceKind::kNone;
  RecorderOptions options;
  options.root_dir = dir.path();
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  MemoryCameraOptions camera_options;
  camera_options.serial = "MEMA";
  MemoryCamera camera(camera_options);
  ASSERT_TRUE(camera.Open().ok() && camera.Start().ok());
  for (int f = 0; f < 4; ++f) {
    ASSERT_TRUE(camera.SoftwareTrigger().ok());
    auto frame = camera.NextFrame(milliseconds(1000));
    ASSERT_TRUE(frame.ok() && frame->has_value());
    ASSERT_TRUE((*recorder)->SubmitFrame(0, f, std::move(**frame)));
  }
  (*recorder)->Stop();
  const auto clean = test::RunLifmcr("info '" + dir.path().string() + "'");
  EXPECT_EQ(clean.exit_code, 0) << clean.out << clean.err;
  // What a crash between the pixel write and the header write leaves.
  const fs::path cut = layout::RawFramePath((*recorder)->sequence_dir(), "MEMA", 3);
  {
    const int fd = ::open(cut.c_str(), O_WRONLY);
    ASSERT_GE(fd, 0);
    const std::string zeros(4096, '\0');
    ASSERT_EQ(::pwrite(fd, zeros.data(), zeros.size(), 0), 4096);
    ::close(fd);
  }
  const auto broken = test::RunLifmcr("info '" + dir.path().string() + "'");
  EXPECT_EQ(broken.exit_code, 1) << broken.out << broken.err;
  EXPECT_NE((broken.out + broken.err).find(cut.filename().string()), std::string::npos)
      << broken.out << broken.err;
}

}  // namespace
}  // namespace lifmcr
