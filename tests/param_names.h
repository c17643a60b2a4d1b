// Names of value-parameterised tests made from their string parameter ("large-drift" ->
// "large_drift"): gtest allows only letters, digits and underscores.
#pragma once

#include <gtest/gtest.h>

#include <string>

namespace certislam::testing {

struct DashesToUnderscores {
    std::string operator()(const ::testing::TestParamInfo<std::string>& info) const {
        std::string name = info.param;
        for (char& c : name) {
            if (c == '-') c = '_';
        }
        return name;
    }
};

}  // namespace certislam::testing
