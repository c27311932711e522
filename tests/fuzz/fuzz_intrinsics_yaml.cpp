// Intrinsics (cameras.yaml / intrinsics.yaml) as `lifmcr depth --intrinsics`
// reads it, and the synth config, both through the strict YAML reader.

#include "replay/synth/cameras_yaml.h"
#include "replay/synth/synth_params.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  const std::string_view text = fuzz::Text(data, size);
  Expected<synth::CameraModelYaml> model = synth::ParseCameraModelYaml(text, "fuzz.yaml", "40398673");
  if (model) {
    fuzz::Require(model->width_px >= 1 && model->height_px >= 1 && model->pixel_size_mm > 0 &&
                      model->mla_to_sensor_mm > 0,
                  "accepted intrinsics are in range");
  }
  (void)synth::ParseSynthConfig(std::string(text), "fuzz.yaml", synth::SynthParams{});
  return 0;
}
