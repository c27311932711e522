#pragma once
// Runs a rig: one grab thread per camera pulling Camera::NextFrame, a Vicon
// thread pulling the Vicon source, a trigger thread for cameras in software
// trigger mode, all started and stopped together; frames and Vicon frames go
// to the recorder (and to an optional observer: the sync assembler, a
// publisher). Health() is a snapshot for the status line.
//
// Frame numbers: a frame's number in the recording is its trigger index. A
// camera this controller triggers answers its triggers in order, all fired
// after every camera was armed: its first good frame is on trigger 0 (after
// any failed frames), whatever its arrival time; ticks whose trigger call
// overran (skipped) are mapped past, since its frame counter does not count
// them. Any other camera's first frame is placed by the sync assembler when there is one
// (the trigger of its FrameSet, so file numbers and trigger indices count
// from one placement), else by device time against a camera on the same
// device clock (sync/first_frame_placement.h, the rule the assembler
// follows), else by host time from the rig's first frame or the software
// trigger schedule; the log says which decided. Every later one by the camera's frame counter
// (frame_id_unwrapper.h, 16-bit wrap aware), so a counter gap is a missing
// file and is counted; after a reconnect (the counter restarts) the silence
// in host time gives the triggers missed.
//
// The same loop drives live cameras, replay cameras (original timing, as
// fast as the consumer takes frames, or per software trigger) and any mix;
// `lifmcr replay` and `lifmcr record` both run through it.
//
// Start-up (start_at_all_armed): cameras on triggers this controller does
// not fire (a trigger box's line, pulsing all the time) are armed one after
// the other, so the first pulses may reach some cameras only. The run's
// trigger 0 is then the first trigger at which every camera was armed
// (sync/armed_start.h, from each camera's arm and first frame): frames
// before it are counted as "before all cameras armed" and not written, and
// files, FrameSets (LCM trigger_index) and the report count from it. Until
// every camera has delivered its first frame (at most all_armed_wait after
// the last arm, or kMaxHeldFrames frames of one camera) the frames are held
// (their pooled buffers), not yet written or observed.
//
// Accounting, per camera: every frame the counter says was produced ends up
// recorded, or lost as one of: incomplete (delivered with a bad status; not
// written), missing by counter gap, driver underrun, recorder drop. With
// software triggers, triggers fired minus the last index + 1 are the frames
// that never came at the end (`no_frame_at_end`).

#include "acquisition/frame_id_unwrapper.h"
#include "acquisition/recorder.h"
#include "drivers/camera.h"
#include "drivers/vicon_source.h"
#include "sync/armed_start.h"
#include "sync/first_frame_placement.h"
#include "sync/frame_set_assembler.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace lifmcr {

struct RigControllerOptions {
  std::chrono::milliseconds frame_timeout{100};  // one NextFrame wait
  // The rig's trigger rate: the Vicon rate / trigger divider (80 / 8 = 10
  // Hz). Software triggers fire at it, and a camera's silence across a
  // reconnect (its counter restarts) is turned into a count of triggers with it.
  double trigger_hz = 10.0;
  // Stale frames in a row (counter behind) taken as a counter restart.
  int stale_frames_for_restart = 3;
  // At Stop, how long the grab threads keep taking frames after the last
  // trigger, so frames in flight are recorded rather than lost.
  std::chrono::milliseconds drain{300};
  // When set, every frame and Vicon frame also goes to the sync assembler
  // (sync/frame_set_assembler.h), which builds one FrameSet per trigger with
  // its Vicon frame; the report gives its association (Vicon frame of
  // trigger 0, complete sets, losses by kind). Files are numbered by the
  // camera's frame counter (exact, and robust to timing) unless
  // number_files_by_sync, which numbers them by the FrameSet's trigger
  // index instead (frames the assembler cannot place are then not written).
  std::optional<FrameSetAssemblerOptions> sync;
  bool number_files_by_sync = false;
  // How often the sync thread polls the assembler for finished FrameSets.
  std::chrono::milliseconds sync_poll{10};
  // Vicon paced by the cameras (a replay at --rate max, where both sources
  // deliver as fast as they are read): 0 takes Vicon frames as they come;
  // n > 0 takes a Vicon frame only while it belongs to a trigger at most n
  // ahead of the slowest camera still delivering (by the cameras' trigger
  // indices and Vicon frame numbers, sync->vicon_divider per trigger), in
  // bursts of at most that many frames at least a millisecond apart: the Vicon
  // frame of trigger k is in before a FrameSet waits for it, and a burst
  // stays small enough for an LCM subscriber's default queue of 30
  // (lcm-logger's cannot be raised). Needs sync (its vicon_divider).
  int vicon_lead_triggers = 0;
  // Per camera, the clock its device timestamps are on (the rig's
  // cameras[].device_clock); "" or no entry: the driver's
  // (CameraInfo::device_clock). The assembler's device_clocks are set from it.
  std::vector<std::string> device_clocks;
  // SCHED_FIFO priority (1..99) of the Vicon thread, 0 to leave it under the
  // ordinary scheduler (acquisition/thread_priority.h). A live Vicon stream
  // wants kLiveViconPriority; a CSV read as fast as possible must not have it
  // (it would hold a core until the file is read).
  int vicon_realtime_priority = 0;
  static constexpr int kLiveViconPriority = 10;
  // SCHED_FIFO priority of the software trigger threads (0: ordinary). They
  // sleep to each tick and make one cheap call (a register write, a counter),
  // so they take little CPU; under the ordinary scheduler a loaded host
  // wakes them late and a tick is skipped (counted lost).
  int trigger_realtime_priority = kLiveViconPriority;
  // Trigger 0 is the first trigger every camera was armed for (see the top);
  // false: the rig's first frame is trigger 0 (software triggers, fired only
  // once every camera is armed; replay; free run).
  bool start_at_all_armed = false;
  // How long after the last camera was armed the others' frames wait for a
  // camera's first frame before the run's trigger 0 is decided without it.
  std::chrono::milliseconds all_armed_wait{1000};
  // Frames of one camera held at most while waiting (within the pool of
  // queue_frames + 4 buffers that `record` gives each camera).
  static constexpr std::size_t kMaxHeldFrames = 6;
  Status Check() const;  // every field (sync: its own Check); the message names the field
};

// Called on a grab thread for every complete frame (with its run index)
// before it goes to the recorder, and on the Vicon thread for every Vicon
// frame. Must be cheap (the sync assembler's Add).
struct RigObserver {
  std::function<void(int camera_index, std::int64_t frame_index, const Frame&)> on_frame;
  std::function<void(const ViconFrame&)> on_vicon;
  // With sync: every FrameSet the controller's assembler emits, in trigger
  // order, on the sync thread (and the rest at Stop); its frames share their
  // pooled buffers. The pipeline takes its sets here: one assembler per run.
  std::function<void(const FrameSet&)> on_frame_set;
};

struct CameraHealth {
  std::string serial;
  double fps = 0;                // frames received per second, last interval
  double mb_per_s = 0;           // megabytes received per second, last interval
  std::uint64_t received = 0;    // complete frames handed to the recorder
  std::uint64_t incomplete = 0;  // delivered with a bad status: lost
  std::uint64_t missing_by_id = 0;
  std::uint64_t stale = 0;            // repeated/late frames, dropped
  std::uint64_t missing_in_gaps = 0;  // triggers missed while the camera was lost (by host time)
  std::uint64_t counter_restarts = 0;
  // Ticks whose software trigger could not be fired in time (the call
  // overran); of them, those of a working camera (its call succeeded, no
  // reconnect) are triggers it never got: lost (the rest are in the silence
  // of a reconnect, missing_in_gaps).
  std::uint64_t triggers_skipped = 0;
  std::uint64_t triggers_not_fired = 0;
  std::uint64_t not_in_any_set =
      0;                       // files numbered by sync: frames off the grid or late, not written
  std::uint64_t triggers = 0;  // software-trigger schedule ticks for this camera
  std::uint64_t failed_since_ok = 0;  // internal: failed frames since the last good one
  std::uint64_t no_frame_at_end = 0;
  std::uint64_t before_all_armed = 0;  // frames on triggers before every camera was armed: not written
  std::uint64_t errors = 0;           // NextFrame errors (device lost)
  std::string last_error;
  std::int64_t last_index = -1;
  // How the first frame was put on the trigger count (FirstPlacement::OneLine).
  std::string first_placement;
  CameraStats driver;
  RecorderCameraStats recorder;

  // Every frame that was produced (or triggered) and is not on disk.
  std::uint64_t Lost() const;
  // "lost 3 [incomplete 0, missing ids 1, ...]": Lost() by cause.
  std::string LossLine() const;
};

struct RigHealth {
  double elapsed_s = 0;
  std::vector<CameraHealth> cameras;
  std::uint64_t triggers_fired = 0;  // software triggers (0 in hardware mode)
  // start_at_all_armed: triggers before every camera was armed (not the
  // run's; their frames not written, not lost).
  std::uint64_t triggers_before_all_armed = 0;
  bool has_vicon = false;
  double vicon_hz = 0;
  ViconSourceStats vicon;
  std::uint64_t vicon_errors = 0;
  RecorderStats recorder;
  // With sync: FrameSets emitted (one per trigger) and how many were complete
  // (every camera's frame and the Vicon frame; without a Vicon source every
  // camera's frame), the losses by kind, per
  // camera association figures, and the Vicon frame of trigger 0.
  bool has_sync = false;
  bool files_numbered_by_sync = false;  // sync losses are then frame losses
  std::uint64_t frame_sets = 0;
  std::uint64_t complete_frame_sets = 0;
  DropCounter sync_drops;
  std::vector<CameraSyncStats> sync_cameras;
  std::optional<std::int64_t> vicon_f0;

  std::uint64_t FramesLost() const;  // cameras + recorder
  // Anything lost: frames, Vicon frames (gaps, malformed), Vicon lines,
  // sync losses (a trigger without a camera's frame or its Vicon frame).
  bool AnythingLost() const;
  // "12.0s cam0 10.0fps 2.6MB/s q0 drop0 | cam1 ... | Vicon 80.0Hz gaps0 | disk backlog 0.0MB"
  std::string StatusLine() const;
  // Several lines: per camera what was kept and what was lost and why.
  std::string FinalReport() const;
  // One line per camera, the Vicon stream and sync that lost anything, with
  // the causes ("camera MEMB: lost 1 [...]"); empty when nothing was lost.
  // For the operator's log (the command writes them at the end of a run).
  std::vector<std::string> LossLines() const;
};

class RigController {
 public:
  // `software_trigger[i]`: camera i is triggered by this controller.
  // `vicon` may be null (no Vicon source). `recorder` must outlive the controller.
  RigController(std::vector<std::unique_ptr<Camera>> cameras, std::vector<bool> software_trigger,
                std::unique_ptr<ViconSource> vicon, Recorder* recorder,
                RigControllerOptions options = {}, RigObserver observer = {});
  ~RigController();  // Stop()
  RigController(const RigController&) = delete;
  RigController& operator=(const RigController&) = delete;

  // Opens every camera (errors name the camera), then starts the Vicon
  // source and every camera, then the threads. On an error nothing is left
  // running.
  Status Start();
  // Stops triggering, drains, stops the cameras and the Vicon source, joins
  // every thread. Idempotent.
  void Stop();

  RigHealth Health();

  // The software-trigger schedule's start, set by Start: tick k fires at
  // ScheduleStart() + k periods. Empty outside Start..Stop and when this
  // controller fires no triggers. On a loaded host Start may return tens of
  // milliseconds after it (the trigger threads it wakes take its CPU), so
  // callers that time their own events against the triggers use this.
  std::optional<std::chrono::steady_clock::time_point> ScheduleStart() const;

  // True when every free-running source has finished (replay ended); the
  // command stops the recording then.
  bool ViconFinished() const;
  // Every camera has delivered all it has (replay cameras only: a live
  // camera never finishes).
  bool CamerasFinished() const;

 private:
  struct CameraSlot {
    std::unique_ptr<Camera> camera;
    bool software_trigger = false;
    FrameIdUnwrapper unwrapper;
    bool lost = false;  // NextFrame reported the device gone
    int stale_in_a_row = 0;
    std::int64_t last_host_ns = 0;                // of the last accepted frame
    std::atomic<std::uint64_t> trigger_ticks{0};  // schedule ticks passed (fired or skipped)
    // Software triggers: (triggers fired before, ticks skipped) per skip, so
    // the grab thread turns the n-th trigger answered into its tick (guarded
    // by mutex; appended before the next trigger is fired).
    std::vector<std::pair<std::uint64_t, std::uint64_t>> skips;
    std::uint64_t fired = 0;  // trigger thread only
    std::int64_t last_answered = -1;  // the last frame's trigger among those fired (mutex)
    mutable std::mutex mutex;                     // guards health below
    CameraHealth health;
    std::uint64_t interval_frames = 0;
    std::uint64_t interval_bytes = 0;
    // Start-up (start_at_all_armed; grab thread only, except health under mutex):
    std::optional<FirstPlacement> first_placed;  // its first frame's placement
    std::string first_suffix;                    // ", after its failed frames"
    std::optional<std::int64_t> first_index;     // trigger of its first good frame
    std::int64_t failed_before_first = 0;
    bool start_counted = false;  // triggers missed before its first frame counted
    std::vector<std::pair<std::int64_t, Frame>> held;  // waiting for the run's trigger 0
    std::thread thread;
  };
  void GrabLoop(int index);
  void ViconLoop();
  // vicon_lead_triggers: whether the next Vicon frame must wait (ViconLoop).
  bool ViconAhead(std::int64_t next_vicon_frame) const;
  // One per software-triggered camera, all on one schedule, so a camera that
  // is slow to take its trigger (lost, reconnecting) delays no other.
  void TriggerLoop(int index);
  // The schedule tick of the `answered`-th software trigger fired to the
  // camera (0-based): `answered` plus the ticks skipped before it. Needs slot.mutex.
  static std::int64_t TickOfTrigger(const CameraSlot& slot, std::int64_t answered);
  void SyncLoop();
  // Trigger index of a camera's first frame: 0 for the rig's first frame,
  // else the trigger periods since it in host time.
  std::int64_t FirstIndexByHostTime(std::int64_t host_ns);
  // Without the assembler's placement: by device time against a camera on
  // the same clock, else FirstIndexByHostTime.
  // The placement's note says why not by device time.
  FirstPlacement PlaceFirstFrame(int index, const Frame& frame);
  // Hands the frames of emitted sets to the recorder (sync thread, or Stop).
  void RecordSets(std::vector<FrameSet> sets);
  // The run's trigger 0 on the placement count: 0 without start_at_all_armed;
  // nullopt while waiting for cameras' first frames (`force`: decide now).
  std::optional<std::int64_t> Origin(bool force);
  // Once the origin is known: the camera's triggers missed before its first
  // frame counted, its held frames written (or counted before all armed).
  void SettleStart(int index, std::int64_t origin);
  // A good frame on trigger `frame_index` (placement count) to the observer
  // and the recorder, numbered from `origin`.
  void Submit(int index, std::int64_t frame_index, std::int64_t origin, Frame frame);

  std::vector<std::unique_ptr<CameraSlot>> slots_;
  std::unique_ptr<ViconSource> vicon_;
  Recorder* recorder_;
  RigControllerOptions options_;
  RigObserver observer_;

  std::atomic<bool> grabbing_{false};
  std::atomic<bool> triggering_{false};
  std::atomic<bool> vicon_running_{false};
  std::thread vicon_thread_;
  std::vector<std::thread> trigger_threads_;
  // Guards ticks_begun_, the stop of triggering_ and the count of ready trigger threads.
  std::mutex trigger_mutex_;
  std::uint64_t ticks_begun_ = 0;  // ticks any camera's trigger thread began firing
  std::condition_variable trigger_ready_;  // Start waits on it for every trigger thread
  std::size_t trigger_threads_ready_ = 0;
  // Set (release) once schedule_start_ is; the trigger threads wait on it.
  std::atomic<bool> schedule_set_{false};
  std::chrono::steady_clock::time_point schedule_start_;
  bool started_ = false;

  std::mutex vicon_mutex_;
  std::uint64_t vicon_interval_frames_ = 0;
  std::uint64_t vicon_errors_ = 0;
  std::optional<std::int64_t> first_vicon_frame_;  // ViconLoop only
  double vicon_hz_ = 0;
  std::mutex anchor_mutex_;
  std::optional<std::int64_t> rig_first_host_ns_;
  std::unique_ptr<FirstFramePlacer> placer_;  // guarded by anchor_mutex_
  std::unique_ptr<ArmedStart> armed_start_;   // start_at_all_armed; guarded by anchor_mutex_
  // CLOCK_REALTIME when the last camera was armed; guarded by anchor_mutex_.
  std::optional<std::int64_t> all_armed_host_ns_;
  std::atomic<bool> origin_known_{false};
  std::atomic<std::int64_t> origin_{0};
  // CLOCK_REALTIME of the first software trigger, when this controller fires them.
  std::optional<std::int64_t> trigger_schedule_host_ns_;
  std::mutex sync_mutex_;  // guards assembler_ and the set counters
  std::unique_ptr<FrameSetAssembler> assembler_;
  std::uint64_t frame_sets_ = 0;
  std::uint64_t complete_frame_sets_ = 0;
  std::atomic<bool> syncing_{false};
  std::thread sync_thread_;
  std::chrono::steady_clock::time_point start_time_;
  std::chrono::steady_clock::time_point last_health_;
};

}  // namespace lifmcr
