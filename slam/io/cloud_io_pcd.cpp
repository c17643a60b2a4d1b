// The PCD reader: header, ASCII, binary and binary_compressed (LZF, PCL's decoder) point data.
// The header is parsed and every size checked against the file here, not by PCL's PCDReader: it
// trusts POINTS x record size and the compressed sizes (a crafted header makes it read or write
// out of bounds), and its errors name neither the line nor the fault.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <pcl/io/lzf.h>

#include "slam/io/cloud_io_parse.h"
#include "slam/io/cloud_io_pcd.h"

namespace certislam::slam {
namespace cloud_io_internal {
namespace {

using Status = CloudReadResult::Status;

struct PcdField {
    std::string name;
    ScalarType type;
    int count = 1;
    std::size_t offset = 0;  ///< byte offset inside one point record (binary layout)
};

struct PcdHeader {
    std::vector<PcdField> fields;
    std::vector<int> sizes, counts;
    std::vector<char> types;
    long long width = -1, height = 1, points = -1;
    std::string data;
    std::size_t data_offset = 0;      ///< first byte after the DATA line
    int data_line = 0;                ///< line number of the DATA line
    std::size_t point_bytes = 0;      ///< bytes per point record
    int xyz[3] = {-1, -1, -1};        ///< field index of x, y, z
    int ascii_xyz[3] = {-1, -1, -1};  ///< token index of x, y, z in an ASCII line
};

std::optional<ScalarType> ToScalarType(char type, int size) {
    if (type == 'F' && (size == 4 || size == 8)) return ScalarType{ScalarKind::kFloat, size};
    const bool int_size = size == 1 || size == 2 || size == 4 || size == 8;
    if (type == 'I' && int_size) return ScalarType{ScalarKind::kInt, size};
    if (type == 'U' && int_size) return ScalarType{ScalarKind::kUint, size};
    return std::nullopt;
}

// Reads one header keyword line into `h`; returns an error text or "".
std::string ParseHeaderLine(const std::vector<std::string_view>& w, PcdHeader& h) {
    const std::string_view key = w[0];
    const std::size_t n = w.size() - 1;
    if (key == "FIELDS" || key == "COLUMNS") {
        for (std::size_t i = 1; i < w.size(); ++i) h.fields.push_back({std::string(w[i]), {}});
    } else if (key == "SIZE" || key == "COUNT") {
        auto& out = key == "SIZE" ? h.sizes : h.counts;
        for (std::size_t i = 1; i < w.size(); ++i) {
            const auto v = ParseCount(w[i]);
            if (!v || *v < 1 || *v > 1 << 20) return std::string(key) + " has a bad value";
            out.push_back(static_cast<int>(*v));
        }
    } else if (key == "TYPE") {
        for (std::size_t i = 1; i < w.size(); ++i) {
            if (w[i].size() != 1) return "TYPE entries must be one of F I U";
            h.types.push_back(w[i][0]);
        }
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
        const auto v = n == 1 ? ParseCount(w[1]) : std::nullopt;
        if (!v) return std::string(key) + " needs one non-negative integer";
        (key == "WIDTH" ? h.width : key == "HEIGHT" ? h.height : h.points) = *v;
    } else if (key == "DATA") {
        if (n != 1) return "DATA needs one of ascii, binary, binary_compressed";
        h.data = std::string(w[1]);
    } else if (key != "VERSION" && key != "VIEWPOINT") {
        return "unknown header keyword '" + std::string(key) + "'";
    }
    return "";
}

// Checks SIZE/TYPE/COUNT against FIELDS and lays out the record; returns an error text or "".
std::string FinishHeader(PcdHeader& h) {
    const std::size_t nf = h.fields.size();
    if (nf == 0) return "no FIELDS line";
    if (h.counts.empty()) h.counts.assign(nf, 1);
    if (h.sizes.size() != nf || h.types.size() != nf || h.counts.size() != nf) {
        return "FIELDS has " + std::to_string(nf) + " entries but SIZE/TYPE/COUNT have " +
               std::to_string(h.sizes.size()) + "/" + std::to_string(h.types.size()) + "/" +
               std::to_string(h.counts.size());
    }
    if (h.points < 0) {
        if (h.width < 0) return "neither POINTS nor WIDTH given";
        const auto wh =
            CheckedMul(static_cast<std::size_t>(h.width), static_cast<std::size_t>(h.height));
        if (!wh || *wh > static_cast<std::size_t>(INT64_MAX)) return "WIDTH x HEIGHT overflows";
        h.points = static_cast<long long>(*wh);
    }
    int token = 0;
    for (std::size_t i = 0; i < nf; ++i) {
        const auto type = ToScalarType(h.types[i], h.sizes[i]);
        if (!type) {
            return "field '" + h.fields[i].name + "' has TYPE " + h.types[i] + " with SIZE " +
                   std::to_string(h.sizes[i]);
        }
        h.fields[i].type = *type;
        h.fields[i].count = h.counts[i];
        h.fields[i].offset = h.point_bytes;
        const auto bytes = CheckedAdd(h.point_bytes, static_cast<std::size_t>(h.sizes[i]) *
                                                         static_cast<std::size_t>(h.counts[i]));
        if (!bytes) return "SIZE x COUNT summed over FIELDS overflows";
        h.point_bytes = *bytes;
        const char* names[3] = {"x", "y", "z"};
        for (int a = 0; a < 3; ++a) {
            if (h.fields[i].name == names[a]) {
                h.xyz[a] = static_cast<int>(i);
                h.ascii_xyz[a] = token;
            }
        }
        token += h.counts[i];
    }
    if (h.xyz[0] < 0 || h.xyz[1] < 0 || h.xyz[2] < 0) return "FIELDS lacks one of x y z";
    return "";
}

// Parses the header; on failure fills `result` and returns false.
bool ParseHeader(const std::string& path, const std::vector<unsigned char>& bytes, PcdHeader& h,
                 CloudReadResult& result) {
    std::size_t offset = 0;
    int line_no = 0;
    while (offset < bytes.size()) {
        const LineView line = NextLine(bytes, offset);
        offset = line.next;
        ++line_no;
        const auto words = SplitWords(line.text);
        if (words.empty() || words[0][0] == '#') continue;
        if (const std::string err = ParseHeaderLine(words, h); !err.empty()) {
            result = Fail(Status::kBadHeader, path, line_no, err);
            return false;
        }
        if (!h.data.empty()) {
            h.data_offset = offset;
            h.data_line = line_no;
            if (const std::string err = FinishHeader(h); !err.empty()) {
                result = Fail(Status::kBadHeader, path, line_no, err);
                return false;
            }
            return true;
        }
    }
    result = Fail(Status::kBadHeader, path, line_no, "no DATA line (not a PCD file?)");
    return false;
}

CloudReadResult ReadAscii(const std::string& path, const std::vector<unsigned char>& bytes,
                          const PcdHeader& h) {
    CloudReadResult result;
    std::size_t offset = h.data_offset;
    int line_no = h.data_line;
    std::size_t tokens = 0;
    for (const auto& f : h.fields) tokens += static_cast<std::size_t>(f.count);
    // A data line holds `tokens` values and as many separators: the file bounds the reserve.
    const std::size_t most = (bytes.size() - offset) / (2 * tokens);
    result.cloud.reserve(std::min(static_cast<std::size_t>(h.points), most));
    long long read = 0;
    while (read < h.points && offset < bytes.size()) {
        const LineView line = NextLine(bytes, offset);
        offset = line.next;
        ++line_no;
        const auto words = SplitWords(line.text);
        if (words.empty()) continue;
        if (words.size() != tokens) {
            return Fail(Status::kBadData, path, line_no,
                        "expected " + std::to_string(tokens) + " values, found " +
                            std::to_string(words.size()));
        }
        double v[3];
        for (int a = 0; a < 3; ++a) {
            const auto parsed = ParseDouble(words[static_cast<std::size_t>(h.ascii_xyz[a])]);
            if (!parsed) return Fail(Status::kBadData, path, line_no, "not a number");
            v[a] = *parsed;
        }
        AddPoint(result, v[0], v[1], v[2]);
        ++read;
    }
    if (read < h.points) {
        return Fail(Status::kTruncated, path, line_no,
                    "POINTS " + std::to_string(h.points) + " but only " + std::to_string(read) +
                        " data lines");
    }
    return result;
}

// Decodes points from a buffer: record-major (binary) or field-major (binary_compressed).
CloudReadResult DecodeBinary(const unsigned char* data, const PcdHeader& h, bool field_major) {
    CloudReadResult result;
    const auto n = static_cast<std::size_t>(h.points);
    result.cloud.reserve(n);
    std::size_t field_start[3], stride[3];
    for (int a = 0; a < 3; ++a) {
        const PcdField& f = h.fields[static_cast<std::size_t>(h.xyz[a])];
        field_start[a] = field_major ? f.offset * n : f.offset;
        stride[a] = field_major ? static_cast<std::size_t>(f.type.size) * f.count : h.point_bytes;
    }
    for (std::size_t i = 0; i < n; ++i) {
        double v[3];
        for (int a = 0; a < 3; ++a) {
            const PcdField& f = h.fields[static_cast<std::size_t>(h.xyz[a])];
            v[a] = DecodeScalar(data + field_start[a] + i * stride[a], f.type);
        }
        AddPoint(result, v[0], v[1], v[2]);
    }
    return result;
}

// A back reference (3 bytes) yields at most 264 bytes, a literal run never more than it reads.
constexpr std::size_t kLzfMaxExpansion = 88;

// "POINTS x B = N" with N in checked arithmetic ("overflows size_t" when it does not fit).
std::string Product(const PcdHeader& h) {
    const auto n = CheckedMul(h.point_bytes, static_cast<std::size_t>(h.points));
    return "POINTS " + std::to_string(h.points) + " x record size " +
           std::to_string(h.point_bytes) + " = " +
           (n ? std::to_string(*n) : std::string("overflows size_t"));
}

CloudReadResult ReadCompressed(const std::string& path, const std::vector<unsigned char>& bytes,
                               const PcdHeader& h) {
    const std::size_t avail = bytes.size() - h.data_offset;
    if (avail < 8) return Fail(Status::kTruncated, path, 0, "binary_compressed sizes missing");
    std::uint32_t compressed = 0, uncompressed = 0;
    std::memcpy(&compressed, bytes.data() + h.data_offset, 4);
    std::memcpy(&uncompressed, bytes.data() + h.data_offset + 4, 4);
    const auto product = CheckedMul(h.point_bytes, static_cast<std::size_t>(h.points));
    if (!product || *product != uncompressed) {
        return Fail(Status::kBadData, path, h.data_line,
                    "binary_compressed at byte " + std::to_string(h.data_offset) +
                        ": uncompressed size " + std::to_string(uncompressed) + " must equal " +
                        Product(h));
    }
    const std::size_t expected = *product;
    if (avail - 8 < compressed) {
        return Fail(Status::kTruncated, path, h.data_line,
                    "binary_compressed at byte " + std::to_string(h.data_offset) + ": " +
                        std::to_string(compressed) + " compressed bytes declared, " +
                        std::to_string(avail - 8) + " present");
    }
    if (expected / kLzfMaxExpansion > compressed) {
        return Fail(Status::kBadData, path, h.data_line,
                    "binary_compressed at byte " + std::to_string(h.data_offset) + ": " +
                        std::to_string(compressed) + " LZF bytes cannot expand to " +
                        std::to_string(expected) + " (LZF expands at most " +
                        std::to_string(kLzfMaxExpansion) + "x)");
    }
    // The sizes are checked above against the file and the header (PCL's reader trusts them and
    // reads past its buffer on a crafted file): only then does PCL's LZF decoder run.
    std::vector<unsigned char> raw(expected);
    if (expected > 0 && pcl::lzfDecompress(bytes.data() + h.data_offset + 8, compressed, raw.data(),
                                           uncompressed) != uncompressed) {
        return Fail(Status::kBadData, path, 0, "binary_compressed: corrupt LZF stream");
    }
    return DecodeBinary(raw.data(), h, /*field_major=*/true);
}

}  // namespace

CloudReadResult ParsePcd(const std::string& path, const std::vector<unsigned char>& bytes) {
    PcdHeader h;
    CloudReadResult result;
    if (!ParseHeader(path, bytes, h, result)) return result;
    if (h.data == "ascii") return ReadAscii(path, bytes, h);
    if (h.data == "binary_compressed") return ReadCompressed(path, bytes, h);
    if (h.data != "binary") {
        return Fail(Status::kUnsupported, path, h.data_line, "DATA '" + h.data + "' unknown");
    }
    const auto expected = CheckedMul(h.point_bytes, static_cast<std::size_t>(h.points));
    const std::size_t avail = bytes.size() - h.data_offset;
    if (!expected || avail < *expected) {
        return Fail(Status::kTruncated, path, h.data_line,
                    "binary data at byte " + std::to_string(h.data_offset) + ": " + Product(h) +
                        " bytes must fit in the file, " + std::to_string(avail) + " present");
    }
    return DecodeBinary(bytes.data() + h.data_offset, h, /*field_major=*/false);
}

}  // namespace cloud_io_internal

CloudReadResult ReadPcd(const std::string& path) {
    bool too_big = false;
    const auto bytes = cloud_io_internal::ReadFileBytes(path, &too_big);
    if (!bytes) return cloud_io_internal::ReadFailure(path, too_big);
    return cloud_io_internal::ParsePcd(path, *bytes);
}

}  // namespace certislam::slam
