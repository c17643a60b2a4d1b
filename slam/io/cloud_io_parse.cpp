// Parsing helpers shared by the PCD and PLY readers.
#include "slam/io/cloud_io_parse.h"

#include <algorithm>
#include <charconv>
#include <fstream>

namespace certislam::slam {
namespace cloud_io_internal {

std::optional<std::vector<unsigned char>> ReadFileBytes(const std::string& path, bool* too_big) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return std::nullopt;
    const std::streamoff size = in.tellg();
    if (size < 0) return std::nullopt;
    if (static_cast<std::size_t>(size) > kMaxCloudFileBytes) {
        if (too_big != nullptr) *too_big = true;
        return std::nullopt;
    }
    std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
    in.seekg(0);
    if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) return std::nullopt;
    return bytes;
}

CloudReadResult ReadFailure(const std::string& path, bool too_big) {
    if (!too_big)
        return Fail(CloudReadResult::Status::kCannotOpen, path, 0, "cannot open or read the file");
    return Fail(CloudReadResult::Status::kUnsupported, path, 0,
                "file is over " + std::to_string(kMaxCloudFileBytes) +
                    " bytes, the largest cloud file read");
}

CloudReadResult Fail(CloudReadResult::Status status, const std::string& path, int line,
                     const std::string& message) {
    CloudReadResult result;
    result.status = status;
    result.error = path;
    if (line > 0) result.error.append(":").append(std::to_string(line));
    result.error.append(": ").append(message);
    return result;
}

std::vector<std::string_view> SplitWords(std::string_view line) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
        std::size_t j = i;
        while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
        if (j > i) words.push_back(line.substr(i, j - i));
        i = j;
    }
    return words;
}

std::optional<double> ParseDouble(std::string_view word) {
    double v = 0.0;
    const char* end = word.data() + word.size();
    const auto [ptr, ec] = std::from_chars(word.data(), end, v);
    if (ec != std::errc() || ptr != end) return std::nullopt;
    return v;
}

std::optional<long long> ParseCount(std::string_view word) {
    long long v = 0;
    const char* end = word.data() + word.size();
    const auto [ptr, ec] = std::from_chars(word.data(), end, v);
    if (ec != std::errc() || ptr != end || v < 0) return std::nullopt;
    return v;
}

LineView NextLine(const std::vector<unsigned char>& bytes, std::size_t offset) {
    const auto* begin = bytes.data() + offset;
    const auto* end = bytes.data() + bytes.size();
    const auto* nl = std::find(begin, end, static_cast<unsigned char>('\n'));
    const std::string_view text(reinterpret_cast<const char*>(begin),
                                static_cast<std::size_t>(nl - begin));
    return {text, static_cast<std::size_t>(nl - bytes.data()) + (nl == end ? 0 : 1)};
}

}  // namespace cloud_io_internal

}  // namespace certislam::slam
