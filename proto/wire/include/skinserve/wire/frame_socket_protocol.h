// The frame socket's protocol (docs/serving/frame-socket.md): a same-host client sends
// StreamSkin's requests and reads StreamSkin's answers over a Unix stream socket the server
// listens on (--frame-socket PATH), without gRPC: no HTTP/2 and none of gRPC's threads
// between the socket and the thread that skins. The client first sends the 8 bytes of
// kFrameSocketHello; then each message either way is a 4-byte little-endian header and that
// many bytes: the client's a serialized SkinRequest (a frame or a tick, exactly as on
// StreamSkin), the server's a serialized SkinResponse part, in request order, each answer
// ending with its `last` part as on StreamSkin. A header with kFrameSocketEndBit set is the
// server's last message: a SkinResponse whose `error` is why the connection ends (code 0:
// the client half-closed and every request was answered).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace skinserve::wire {

inline constexpr std::string_view kFrameSocketHello = "SKFRAME1";
inline constexpr uint32_t kFrameSocketEndBit = 0x80000000u;
inline constexpr uint32_t kFrameSocketSizeMask = 0x7fffffffu;
inline constexpr std::size_t kFrameSocketHeaderBytes = 4;

// A message's header, little-endian, into and out of its 4 bytes.
inline void WriteFrameSocketHeader(uint32_t header, unsigned char* bytes) {
  for (std::size_t i = 0; i < kFrameSocketHeaderBytes; ++i) {
    bytes[i] = static_cast<unsigned char>(header >> (8 * i));
  }
}
inline uint32_t ReadFrameSocketHeader(const unsigned char* bytes) {
  uint32_t header = 0;
  for (std::size_t i = 0; i < kFrameSocketHeaderBytes; ++i) {
    header |= static_cast<uint32_t>(bytes[i]) << (8 * i);
  }
  return header;
}

}  // namespace skinserve::wire
