#pragma once
// Raytrix MLA calibration XML, `RayCalibData` version 1.0 (paper
// supplementary "MLA Calibration File"). This is
// the "previous standard" the LiFMCR files were converted to; newer RxLive
// exports use another schema and are rejected with a message saying so.
//
// Schema read and written (every element required except <distortion>):
//   <RayCalibData version="1.0">
//     <offset units="pix"><x/><y/></offset>          image centre -> reference lens, y UP
//     <diameter units="pix"/> <rotation units="rad"/> <lens_border units="pix"/>
//     <tcp units="virtual_depth"/>
//     <lens_base_x units="lens"><x/><y/></lens_base_x>   (also lens_base_y, sub_grid_base)
//     <distortion type="radial">                      optional: absent = constant, no parameters
//       <function>constant|Brown</function>
//       <parameter count="N">p1;p2;...</parameter>    text "0" when N = 0
//       <offset units="pix"><x/><y/></offset>        distortion centre
//     </distortion>
//     <lens_type id="0|1|2">                          exactly three, ids {0,1,2} in any order
//       <offset units="lens"><x/><y/></offset>
//       <depth_range units="virtual_depth"><min/><max/></depth_range>
//     </lens_type>
//   </RayCalibData>
// Elements not named above are ignored (a converted file may carry extras).
//
// Checks (CheckMlaCalibration): every value finite and within kMlaLimits
// (what a real camera and lens can be; values outside crash or exhaust
// memory later in processing); 0 <= lens_border < diameter/2; |lens_base_x| and |lens_base_y| within 1e-3
// of 1 and |cos(angle between them)| within 1e-3 of 1/2 (60 or 120 degrees;
// signs vary between real files and are not checked); depth_range
// min < max (an empty range leaves the lens type sharp nowhere); distortion
// function "constant" or "Brown". Any rotation is
// accepted (one real file has pi/2 with transposed bases).
//
// Errors name the file, the line and the element path, e.g.
//   "R42.xml:14: /RayCalibData/lens_base_y: missing element /RayCalibData/lens_base_y/y".

#include "config/error.h"
#include "config/mla.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace lifmcr {

// Ranges of a real Raytrix-style MLA calibration (README, "Limits of every
// input"). The samples: diameter 23-38 px, rotation up to pi/2, tcp ~2.2,
// depth ranges within 1..100, offsets of tens of pixels, 0-5 parameters.
struct MlaLimits {
  std::uint64_t max_file_bytes = 1 << 20;  // real files are ~3 KB
  double max_offset_px = 32768;            // |offset|, |distortion offset| per axis: the sensor size
  double min_diameter_px = 5;              // fewer pixels per micro image hold no depth
  double max_diameter_px = 500;
  double max_abs_rotation_rad = 6.2832;    // any angle, once round
  double min_virtual_depth = 0.01;         // tcp > 0
  double max_virtual_depth = 1000;         // tcp and depth_range (samples: <= 100)
  double max_basis_lens = 10;              // |sub_grid_base| ~3.46, lens_type offsets ~1
  std::size_t max_distortion_parameters = 16;
  double max_abs_distortion_parameter = 1e6;
};
inline constexpr MlaLimits kMlaLimits{};

// Reads and checks an MLA calibration file.
Expected<MlaCalibration> ReadMlaXml(const std::filesystem::path& path);
// Same, from text already in memory; `file_label` names it in messages.
Expected<MlaCalibration> ParseMlaXml(std::string_view text, const std::string& file_label);

// Writes `calibration` in RxLive's style (see FormatMlaXml) after
// CheckMlaCalibration; nothing is written when the check fails.
Status WriteMlaXml(const std::filesystem::path& path, const MlaCalibration& calibration);
// RxLive style: no XML declaration, 2-space indent, CRLF line endings, no
// newline after the closing root tag, `units` attributes, numbers in fixed
// notation with 12 decimals ("34.864704132080"). A value that 12 decimals
// cannot hold to 1e-12 relative (e.g. 2.54e-5 or a Brown coefficient) is
// written in the shortest form that reads back exactly instead, so
// ParseMlaXml(FormatMlaXml(c)) equals c to 1e-12 relative. A calibration read
// from an RxLive file is reproduced byte for byte.
std::string FormatMlaXml(const MlaCalibration& calibration);

// The checks listed above, on a calibration held in memory. The error
// names the element path of the offending value:
//   "MlaCalibration: /RayCalibData/diameter: expected a diameter > 0 px, got -1".
Status CheckMlaCalibration(const MlaCalibration& calibration);

}  // namespace lifmcr
