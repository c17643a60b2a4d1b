// Kinds of configuration key (number in a range, flag, string, path, choice, 3-vector, the robot
// list): each binds a YAML value to a TeamConfig field with its type, range and error text.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "bin/config/config_keys.h"
#include "bin/config/team_config.h"

namespace certislam::bin::config_key_kinds {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// An interval of numbers; open ends exclude their bound.
struct Range {
    double lo = -kInf;
    double hi = kInf;
    bool lo_open = false;
    bool hi_open = false;

    bool Contains(double v) const {
        return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
    }
};

inline std::string Number(double v) {
    char buffer[64];
    // Whole numbers as integers (to_chars' shortest form would print 100000 as 1e+05).
    const bool whole = std::isfinite(v) && std::abs(v) < 1e15 && v == std::floor(v);
    const auto end =
        whole ? std::to_chars(buffer, buffer + sizeof(buffer), static_cast<long long>(v)).ptr
              : std::to_chars(buffer, buffer + sizeof(buffer), v).ptr;
    return std::string(buffer, end);
}

inline std::string Text(const Range& r) {
    if (std::isinf(r.lo) && std::isinf(r.hi)) return "";
    if (std::isinf(r.hi)) return (r.lo_open ? "> " : ">= ") + Number(r.lo);
    if (std::isinf(r.lo)) return (r.hi_open ? "< " : "<= ") + Number(r.hi);
    return (r.lo_open ? "(" : "[") + Number(r.lo) + ", " + Number(r.hi) + (r.hi_open ? ")" : "]");
}

inline std::string Quote(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        out += c;
    }
    return out + "\"";
}

/// The scalar of `node` as T; `what` names the type in the error.
template <class T>
T Scalar(const YAML::Node& node, const std::string& what, bool quoted_ok = false) {
    if (node.IsNull()) throw std::invalid_argument("has no value (expected " + what + ")");
    if (!node.IsScalar()) {
        throw std::invalid_argument("must be " + what + ", not a " +
                                    (node.IsMap() ? "mapping" : "list"));
    }
    if (!quoted_ok && node.Tag() == "!") {
        throw std::invalid_argument("must be " + what + ", not the quoted string \"" +
                                    node.Scalar() + "\"");
    }
    try {
        return node.as<T>();
    } catch (const YAML::Exception&) {
        throw std::invalid_argument("must be " + what + ", not '" + node.Scalar() + "'");
    }
}

inline double InRange(double v, const Range& r) {
    if (!std::isfinite(v) || !r.Contains(v)) {
        throw std::invalid_argument(Number(v) + " is out of range " + Text(r));
    }
    return v;
}

/// An integer or real number field of type T.
template <class T, class G>
ConfigKey Num(std::string path, G get, Range range, std::string doc, std::string kinds = "") {
    constexpr bool kInt = std::is_integral_v<T>;
    ConfigKey key{std::move(path),  kInt ? "integer" : "number",
                  Text(range),      std::move(doc),
                  std::move(kinds), nullptr,
                  nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return kInt ? std::to_string(static_cast<long long>(get(copy, r)))
                    : Number(static_cast<double>(get(copy, r)));
    };
    key.read = [get, range](const YAML::Node& n, int r, TeamConfig* c) {
        if constexpr (kInt) {
            get(*c, r) = static_cast<T>(
                InRange(static_cast<double>(Scalar<long long>(n, "an integer")), range));
        } else {
            get(*c, r) = static_cast<T>(InRange(Scalar<double>(n, "a number"), range));
        }
    };
    return key;
}

template <class G>
ConfigKey Flag(std::string path, G get, std::string doc, std::string kinds = "") {
    ConfigKey key{std::move(path),  "bool",  "true, false", std::move(doc),
                  std::move(kinds), nullptr, nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return std::string(get(copy, r) ? "true" : "false");
    };
    key.read = [get](const YAML::Node& n, int r, TeamConfig* c) {
        get(*c, r) = Scalar<bool>(n, "true or false");
    };
    return key;
}

/// A string; a "path" is resolved against the configuration file's folder when relative.
template <class G>
ConfigKey Str(std::string path, G get, std::string doc, std::string kinds = "",
              bool is_path = false) {
    ConfigKey key{
        std::move(path), is_path ? "path" : "string", "", std::move(doc), std::move(kinds), nullptr,
        nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return Quote(get(copy, r));
    };
    key.read = [get, is_path](const YAML::Node& n, int r, TeamConfig* c) {
        std::string value = Scalar<std::string>(n, "a string", true);
        if (is_path && !value.empty() && value.front() != '/') {
            value = (std::filesystem::path(c->path).parent_path() / value).string();
        }
        get(*c, r) = value;
    };
    return key;
}

template <class G>
ConfigKey FilePath(std::string path, G get, std::string doc, std::string kinds = "") {
    return Str(std::move(path), get, std::move(doc), std::move(kinds), true);
}

/// One of named values of an enum (or string) field.
template <class E, class G>
ConfigKey Choice(std::string path, G get, std::vector<std::pair<std::string, E>> names,
                 std::string doc, std::string kinds = "") {
    std::string range;
    for (const auto& [name, value] : names) range += (range.empty() ? "" : ", ") + name;
    ConfigKey key{std::move(path),  "choice", range,  std::move(doc),
                  std::move(kinds), nullptr,  nullptr};
    key.show = [get, names](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        for (const auto& [name, value] : names) {
            if (get(copy, r) == value) return name;
        }
        return std::string("?");
    };
    key.read = [get, names, range](const YAML::Node& n, int r, TeamConfig* c) {
        const auto text = Scalar<std::string>(n, "one of " + range, true);
        for (const auto& [name, value] : names) {
            if (text == name) {
                get(*c, r) = value;
                return;
            }
        }
        throw std::invalid_argument("\"" + text + "\" is not one of " + range);
    };
    return key;
}

/// A list of exactly 3 finite numbers.
template <class G>
ConfigKey Vec3(std::string path, G get, std::string doc, std::string kinds) {
    ConfigKey key{std::move(path),  "list",  "3 numbers", std::move(doc),
                  std::move(kinds), nullptr, nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        const Eigen::Vector3d v = get(copy, r);
        return "[" + Number(v.x()) + ", " + Number(v.y()) + ", " + Number(v.z()) + "]";
    };
    key.read = [get](const YAML::Node& n, int r, TeamConfig* c) {
        if (!n.IsSequence() || n.size() != 3) throw std::invalid_argument("must be 3 numbers");
        for (int i = 0; i < 3; ++i) get(*c, r)[i] = InRange(Scalar<double>(n[i], "a number"), {});
    };
    return key;
}

inline ConfigKey RobotList() {
    ConfigKey key{"robots", "list",  "0, 1, ..., N-1", "the team: robot ids, ascending from 0",
                  "",       nullptr, nullptr};
    key.show = [](const TeamConfig& c, int) {
        std::string out;
        for (const int r : c.robots) out += (out.empty() ? "" : ", ") + std::to_string(r);
        return "[" + out + "]";
    };
    key.read = [](const YAML::Node& n, int, TeamConfig* c) {
        if (!n.IsSequence()) throw std::invalid_argument("must be a list of robot ids [0, 1, ...]");
        c->robots.clear();
        for (const auto& item : n) c->robots.push_back(Scalar<int>(item, "an integer"));
        if (c->robots.empty()) throw std::invalid_argument("must not be empty");
        for (size_t k = 0; k < c->robots.size(); ++k) {
            if (c->robots[k] != static_cast<int>(k)) {
                throw std::invalid_argument("must be 0, 1, ..., N-1");
            }
        }
    };
    return key;
}

}  // namespace certislam::bin::config_key_kinds
