// Paths into the shared data folder (CERTISLAM_DATA_DIR, defined for every test by
// tests/CMakeLists.txt): the benchmark g2o files and the LiDAR samples the tests read.
#pragma once

#include <string>

namespace certislam::test_data {

/// CERTISLAM_DATA_DIR/`relative`.
inline std::string DataPath(const std::string& relative) {
    return std::string(CERTISLAM_DATA_DIR) + "/" + relative;
}

/// A benchmark pose graph: CERTISLAM_DATA_DIR/g2o/`name`.
inline std::string G2oPath(const std::string& name) { return DataPath("g2o/" + name); }

}  // namespace certislam::test_data
