// The end-of-stream markers: reason strings of the Shutdown that closes each actor stream, in
// one place so a reader includes no sibling actor's header to recognise them.
#pragma once

namespace certislam::actors {

/// Ends the keyframe stream (ingest actor).
inline constexpr const char* kEndOfKeyframes = "end of keyframes";
/// Ends a descriptor stream (descriptor actor).
inline constexpr const char* kEndOfDescriptors = "end of descriptors";
/// Ends a loop stream: the matcher will find no more loops (loop matcher actor).
inline constexpr const char* kEndOfLoops = "end of loops";

}  // namespace certislam::actors
