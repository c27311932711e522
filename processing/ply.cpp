#include "processing/ply.h"

#include <bit>
#include <cstring>
#include <fstream>
#include <string>

namespace lifmcr::processing {

static_assert(std::endian::native == std::endian::little,
              "the PLY records are written in the host's byte order");

Status WritePly(const std::filesystem::path& path, const PointCloud& cloud, bool uncertainty) {
  const std::size_t n = cloud.points_mm.size();
  if (n == 0) return Error{path.string() + ": no points to write"};
  if (cloud.rgb.size() != n || (uncertainty && cloud.sigma_z_mm.size() != n))
    return Error{path.string() + ": point, colour and sigma counts differ"};
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Error{path.string() + ": cannot open for writing"};
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment lifmcr: camera frame, mm\n";
  header += "element vertex " + std::to_string(n) + "\n";
  header += "property float x\nproperty float y\nproperty float z\n";
  header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (uncertainty) header += "property float sigma_z_mm\n";
  header += "end_header\n";
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  char record[19];
  const std::size_t bytes = uncertainty ? 19 : 15;
  for (std::size_t i = 0; i < n; ++i) {
    std::memcpy(record, cloud.points_mm[i].data(), 12);
    std::memcpy(record + 12, cloud.rgb[i].data(), 3);
    if (uncertainty) std::memcpy(record + 15, &cloud.sigma_z_mm[i], 4);
    out.write(record, static_cast<std::streamsize>(bytes));
  }
  out.close();
  if (!out) return Error{path.string() + ": write failed"};
  return Status::Ok();
}

}  // namespace lifmcr::processing
