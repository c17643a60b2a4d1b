// The PLY reader: vertex x y z of ascii and binary_little_endian files.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "slam/io/cloud_io_parse.h"
#include "slam/io/cloud_io_ply.h"

namespace certislam::slam {
namespace {

using namespace cloud_io_internal;
using Status = CloudReadResult::Status;

struct PlyProperty {
    std::string name;
    ScalarType type;        ///< the value type (the item type of a list)
    bool is_list = false;   ///< `property list COUNT_TYPE ITEM_TYPE NAME`
    ScalarType count_type;  ///< type of a list's length
};

struct PlyElement {
    std::string name;
    long long count = 0;
    std::vector<PlyProperty> properties;
};

struct PlyHeader {
    bool binary = false;
    std::vector<PlyElement> elements;
    std::size_t data_offset = 0;
    int end_line = 0;
};

std::optional<ScalarType> PlyType(std::string_view name) {
    if (name == "char" || name == "int8") return ScalarType{ScalarKind::kInt, 1};
    if (name == "uchar" || name == "uint8") return ScalarType{ScalarKind::kUint, 1};
    if (name == "short" || name == "int16") return ScalarType{ScalarKind::kInt, 2};
    if (name == "ushort" || name == "uint16") return ScalarType{ScalarKind::kUint, 2};
    if (name == "int" || name == "int32") return ScalarType{ScalarKind::kInt, 4};
    if (name == "uint" || name == "uint32") return ScalarType{ScalarKind::kUint, 4};
    if (name == "float" || name == "float32") return ScalarType{ScalarKind::kFloat, 4};
    if (name == "double" || name == "float64") return ScalarType{ScalarKind::kFloat, 8};
    return std::nullopt;
}

// Reads one header line into `h`; returns an error text or "".
std::string ParseHeaderLine(const std::vector<std::string_view>& w, PlyHeader& h) {
    if (w[0] == "format") {
        if (w.size() != 3) return "format needs a type and a version";
        if (w[1] == "ascii") return "";
        if (w[1] == "binary_little_endian") {
            h.binary = true;
            return "";
        }
        return "format '" + std::string(w[1]) + "' is not supported (ascii, binary_little_endian)";
    }
    if (w[0] == "element") {
        const auto count = w.size() == 3 ? ParseCount(w[2]) : std::nullopt;
        if (!count) return "element needs a name and a non-negative count";
        h.elements.push_back({std::string(w[1]), *count, {}});
        return "";
    }
    if (w[0] == "property") {
        if (h.elements.empty()) return "property before any element";
        PlyProperty p;
        if (w.size() == 5 && w[1] == "list") {
            const auto ct = PlyType(w[2]), it = PlyType(w[3]);
            if (!ct || !it || ct->kind == ScalarKind::kFloat) return "bad list property types";
            p = {std::string(w[4]), *it, true, *ct};
        } else if (w.size() == 3) {
            const auto t = PlyType(w[1]);
            if (!t) return "unknown property type '" + std::string(w[1]) + "'";
            p = {std::string(w[2]), *t, false, {}};
        } else {
            return "malformed property line";
        }
        h.elements.back().properties.push_back(p);
        return "";
    }
    if (w[0] == "comment" || w[0] == "obj_info") return "";
    return "unknown header keyword '" + std::string(w[0]) + "'";
}

bool ParseHeader(const std::string& path, const std::vector<unsigned char>& bytes, PlyHeader& h,
                 CloudReadResult& result) {
    std::size_t offset = 0;
    int line_no = 0;
    while (offset < bytes.size()) {
        const LineView line = NextLine(bytes, offset);
        offset = line.next;
        ++line_no;
        const auto words = SplitWords(line.text);
        if (line_no == 1) {
            if (words.size() != 1 || words[0] != "ply") {
                result = Fail(Status::kBadHeader, path, 1, "first line is not 'ply'");
                return false;
            }
            continue;
        }
        if (words.empty()) continue;
        if (words[0] == "end_header") {
            h.data_offset = offset;
            h.end_line = line_no;
            return true;
        }
        if (const std::string err = ParseHeaderLine(words, h); !err.empty()) {
            result = Fail(Status::kBadHeader, path, line_no, err);
            return false;
        }
    }
    result = Fail(Status::kBadHeader, path, line_no, "no end_header line");
    return false;
}

// Bytes of the smallest record of `e` (a list of length 0 holds only its count).
std::size_t MinRecordBytes(const PlyElement& e) {
    std::size_t bytes = 0;
    for (const PlyProperty& p : e.properties) {
        bytes += static_cast<std::size_t>(p.is_list ? p.count_type.size : p.type.size);
    }
    return bytes;
}

// Walks binary records of one element; `on_record(values)` sees every scalar property.
// Returns an error text (data ends early, negative list length) or "".
template <typename OnRecord>
std::string WalkBinary(const std::vector<unsigned char>& bytes, std::size_t& offset,
                       const PlyElement& e, OnRecord on_record) {
    const auto least = CheckedMul(static_cast<std::size_t>(e.count), MinRecordBytes(e));
    if (!least || *least > bytes.size() - offset) {
        return std::to_string(e.count) + " records of at least " +
               std::to_string(MinRecordBytes(e)) + " bytes do not fit in the " +
               std::to_string(bytes.size() - offset) + " bytes left";
    }
    if (e.properties.empty()) return "";  // records without properties hold no bytes
    std::vector<double> values(e.properties.size(), 0.0);
    for (long long r = 0; r < e.count; ++r) {
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
            const PlyProperty& p = e.properties[k];
            std::size_t items = 1;
            if (p.is_list) {
                const auto cs = static_cast<std::size_t>(p.count_type.size);
                if (bytes.size() - offset < cs) return "data ends inside a list length";
                const double length = DecodeScalar(bytes.data() + offset, p.count_type);
                if (length < 0) return "negative list length " + std::to_string(length);
                items = static_cast<std::size_t>(length);  // < 2^32: count types are <= 4 bytes
                offset += cs;
            }
            const std::size_t need = items * static_cast<std::size_t>(p.type.size);
            if (bytes.size() - offset < need) return "data ends inside a record";
            if (!p.is_list) values[k] = DecodeScalar(bytes.data() + offset, p.type);
            offset += need;
        }
        on_record(values);
    }
    return "";
}

CloudReadResult ReadData(const std::string& path, const std::vector<unsigned char>& bytes,
                         const PlyHeader& h, std::size_t vertex, const int xyz[3]) {
    CloudReadResult result;
    std::size_t offset = h.data_offset;
    int line_no = h.end_line;
    for (std::size_t e = 0; e <= vertex; ++e) {
        const PlyElement& el = h.elements[e];
        const bool is_vertex = e == vertex;
        // Every record takes a line (ascii) or at least one byte (binary x y z): bounded.
        if (is_vertex) {
            result.cloud.reserve(
                std::min(static_cast<std::size_t>(el.count), bytes.size() - offset));
        }
        auto on_record = [&](const std::vector<double>& v) {
            if (is_vertex) AddPoint(result, v[xyz[0]], v[xyz[1]], v[xyz[2]]);
        };
        if (h.binary) {
            const std::size_t at = offset;
            if (const std::string err = WalkBinary(bytes, offset, el, on_record); !err.empty()) {
                return Fail(Status::kTruncated, path, 0,
                            "element '" + el.name + "' at byte " + std::to_string(at) + ": " + err);
            }
            continue;
        }
        std::vector<double> values(el.properties.size(), 0.0);
        for (long long r = 0; r < el.count; ++r) {
            if (offset >= bytes.size()) {
                return Fail(Status::kTruncated, path, line_no,
                            "data ends inside element '" + el.name + "' (" +
                                std::to_string(el.count) + " records declared)");
            }
            const LineView line = NextLine(bytes, offset);
            offset = line.next;
            ++line_no;
            if (!is_vertex) continue;
            const auto words = SplitWords(line.text);
            std::size_t w = 0;
            for (std::size_t k = 0; k < el.properties.size(); ++k) {
                const auto parsed = w < words.size() ? ParseDouble(words[w]) : std::nullopt;
                if (!parsed) return Fail(Status::kBadData, path, line_no, "missing or bad value");
                values[k] = *parsed;
                if (!el.properties[k].is_list) {
                    ++w;
                    continue;
                }
                // A list length must be a whole number of the values left on the line.
                if (!(*parsed >= 0) || *parsed != std::floor(*parsed) ||
                    *parsed > static_cast<double>(words.size() - w - 1)) {
                    return Fail(Status::kBadData, path, line_no,
                                "list length " + std::string(words[w]) +
                                    " is not a count of the values that follow");
                }
                w += 1 + static_cast<std::size_t>(*parsed);
            }
            on_record(values);
        }
    }
    return result;
}

}  // namespace

CloudReadResult ReadPly(const std::string& path) {
    bool too_big = false;
    const auto bytes = ReadFileBytes(path, &too_big);
    if (!bytes) return ReadFailure(path, too_big);
    PlyHeader h;
    CloudReadResult result;
    if (!ParseHeader(path, *bytes, h, result)) return result;
    std::size_t vertex = h.elements.size();
    for (std::size_t e = 0; e < h.elements.size(); ++e) {
        if (h.elements[e].name == "vertex") vertex = e;
    }
    if (vertex == h.elements.size()) return Fail(Status::kBadHeader, path, 0, "no vertex element");
    int xyz[3] = {-1, -1, -1};
    const auto& props = h.elements[vertex].properties;
    for (std::size_t k = 0; k < props.size(); ++k) {
        const char* names[3] = {"x", "y", "z"};
        for (int a = 0; a < 3; ++a) {
            if (props[k].name == names[a] && !props[k].is_list) xyz[a] = static_cast<int>(k);
        }
    }
    if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) {
        return Fail(Status::kBadHeader, path, 0, "vertex element lacks one of x y z");
    }
    return ReadData(path, *bytes, h, vertex, xyz);
}

}  // namespace certislam::slam
