#pragma once
// Binary little-endian PLY of a PointCloud (point_cloud.h), the format every
// point-cloud viewer opens (MeshLab, CloudCompare, Open3D, PCL):
//   ply / format binary_little_endian 1.0 / element vertex N /
//   property float x, y, z (mm, camera frame) / property uchar red, green, blue
//   [/ property float sigma_z_mm] / end_header, then N packed records.
// Written with one buffered stream; the records are 15 (19) bytes each.

#include "config/error.h"
#include "processing/point_cloud.h"

#include <filesystem>

namespace lifmcr::processing {

// `uncertainty`: add sigma_z_mm per point (NaN where the depth was filled).
// An empty cloud is an error (a PLY with no vertices helps no one).
Status WritePly(const std::filesystem::path& path, const PointCloud& cloud, bool uncertainty);

}  // namespace lifmcr::processing
