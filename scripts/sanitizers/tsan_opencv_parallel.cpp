// Linked into every executable of the Tsan build type only (CMakeLists.txt,
// end): OpenCV's parallel loops run through TBB code that ThreadSanitizer sees.
//
// cv::parallel_for_ (inside cv::resize, cv::remap and the others, and in
// synth's scene) runs on oneTBB through OpenCV's built-in TBB backend, whose
// TBB header code (the loop's tasks, the wait_context that each worker
// releases when its part is done, OpenCV's function-local static task_arena)
// is compiled inside libopencv_core, which Debian does not build with TSan.
// Even with a TSan-built libtbb (docs/testing.md), TSan then sees the workers'
// accesses and the caller's wait, but not the release that orders them; it
// reported the caller's next use of its stack (a new task_group_context, a
// Status) as racing with a worker's earlier read of the finished loop's
// context or body, and one worker's use of OpenCV's lazily made arena as
// racing with another's construction of it (test_apps_record_publish,
// ReplayBayer). Those accesses are in libtbb and in our code, so neither a
// `called_from_lib:` entry (it only silences interceptors called from a
// library) nor a suppression narrower than every report with an OpenCV frame
// could hide them, and that one would hide races in our loop bodies too.
//
// OpenCV's documented way to run its loops on another thread pool is to
// replace the parallel_for backend (opencv2/core/parallel/parallel_backend.hpp).
// Its header-only TBB backend, compiled here with -fsanitize=thread, makes the
// same calls as the built-in one (tbb::task_arena::execute of a
// tbb::parallel_for over the stripes), now in instrumented code, so every
// hand-over is visible. Installed before main() (a static initialiser; the
// header asks for no other threads and no OpenCV work yet). The Release and
// Asan builds keep OpenCV's built-in backend.

#include <memory>
#include <opencv2/core/parallel/backend/parallel_for.tbb.hpp>

namespace {

const bool kInstrumentedOpenCvLoops = [] {
  cv::parallel::setParallelForBackend(std::make_shared<cv::parallel::tbb::ParallelForBackend>());
  return true;
}();

}  // namespace
