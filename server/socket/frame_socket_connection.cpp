#include "socket/frame_socket_connection.h"

#include <fmt/format.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "skinserve/wire/conversions.h"
#include "skinserve/wire/frame_socket_protocol.h"

namespace skinserve::server {
namespace {

// The receive buffer a connection starts with, and keeps after a larger request.
constexpr std::size_t kInitialBufferBytes = 64 << 10;
constexpr std::size_t kHeaderBytes = wire::kFrameSocketHeaderBytes;
// Parts go out in one sendmsg each: the header and the part's slices.
constexpr std::size_t kMaxIovecs = 64;

timeval TimevalOf(double seconds) {
  const auto whole = static_cast<time_t>(seconds);
  return {whole, static_cast<suseconds_t>((seconds - static_cast<double>(whole)) * 1e6)};
}

// Sends all of `iov` (advanced in place over partial writes); false if the client is gone.
bool SendAll(int fd, iovec* iov, std::size_t count) {
  while (count > 0) {
    msghdr msg = {};
    msg.msg_iov = iov;
    msg.msg_iovlen = count;
    const ssize_t sent = sendmsg(fd, &msg, MSG_NOSIGNAL);
    if (sent < 0) {
      if (errno == EINTR) continue;
      return false;  // EPIPE, ECONNRESET, or EAGAIN after SO_SNDTIMEO: the client stopped reading
    }
    auto left = static_cast<std::size_t>(sent);
    while (count > 0 && left >= iov->iov_len) {
      left -= iov->iov_len;
      ++iov;
      --count;
    }
    if (count > 0) {
      iov->iov_base = static_cast<char*>(iov->iov_base) + left;
      iov->iov_len -= left;
    }
  }
  return true;
}

}  // namespace

FrameSocketConnection::FrameSocketConnection(int fd, FrameSocketAccess access, double idle_seconds)
    : fd_(fd),
      access_(std::move(access)),
      idle_seconds_(idle_seconds),
      idle_ms_(static_cast<int>(std::min(idle_seconds * 1000, 2.0e9))),
      reader_(access_.budget, access_.limits),
      ticks_(static_cast<FrameJob::Listener*>(this), access_.budget) {
  // A client that stops reading its answers is dropped after --stream-idle-seconds (a quiet
  // one ends after as long: Fill's poll).
  const timeval timeout = TimevalOf(idle_seconds);
  setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
}

FrameSocketConnection::~FrameSocketConnection() {
  if (job_) job_->DropWire();
  ticks_.DropWire();
  access_.budget->Release(charged_);
  close(fd_);
}

void FrameSocketConnection::Drain() {
  draining_.store(true);
  shutdown(fd_, SHUT_RD);  // a blocked recv returns; the client's later sends fail
}

void FrameSocketConnection::Refuse(const Status& status) { SendEnd(status); }

void FrameSocketConnection::Serve() {
  End end = Fill(wire::kFrameSocketHello.size(), true);
  if (!end && std::memcmp(buffer_.data() + read_begin_, wire::kFrameSocketHello.data(),
                          wire::kFrameSocketHello.size()) != 0) {
    end =
        InvalidArgument(fmt::format("the frame socket's protocol begins with the 8 bytes '{}' "
                                    "(docs/serving/frame-socket.md)",
                                    wire::kFrameSocketHello));
  }
  read_begin_ += wire::kFrameSocketHello.size();
  if (!end && !access_.allowed.ok()) end = access_.allowed;
  if (!end && access_.engine == nullptr) {
    end = Unavailable("the server is starting: backends are being built");
  }
  while (!end) end = ServeOne();
  SendEnd(*end);
}

FrameSocketConnection::End FrameSocketConnection::ServeOne() {
  if (draining_.load()) return Unavailable(QuietOrDrained("the server is shutting down"));
  if (End end = Fill(kHeaderBytes, true)) return end;
  const uint32_t header = wire::ReadFrameSocketHeader(
      reinterpret_cast<const unsigned char*>(buffer_.data()) + read_begin_);
  const uint64_t limit = std::max<uint64_t>(access_.limits.max_tick_bytes, kMaxFrameRequestBytes);
  if ((header & wire::kFrameSocketEndBit) != 0 || header > limit) {
    // Refused before a byte of it is read or held: its size alone breaks the limit.
    return ResourceExhausted(fmt::format(
        "a request of {} bytes is over the {} a request may hold (--max-tick-bytes for ticks, "
        "4 MiB for frames)",
        header & wire::kFrameSocketSizeMask, limit));
  }
  if (End end = Fill(kHeaderBytes + header, false)) return end;
  read_begin_ += kHeaderBytes;
  if (access_.counters != nullptr) access_.counters->requests.fetch_add(1);
  End end = Answer(header);
  read_begin_ += header;
  if (read_begin_ == read_end_) {
    read_begin_ = read_end_ = 0;
    if (buffer_.size() > kKeptRequestBytes) {  // a large request's room goes with it
      std::vector<std::byte>(kInitialBufferBytes).swap(buffer_);
      access_.budget->Release(charged_ - kInitialBufferBytes);
      charged_ = kInitialBufferBytes;
    }
  }
  return end;
}

FrameSocketConnection::End FrameSocketConnection::Answer(std::size_t size) {
  grpc::Slice slice(buffer_.data() + read_begin_, size, grpc::Slice::STATIC_SLICE);
  grpc::ByteBuffer bytes(&slice, 1);
  Status read = reader_.Read(&bytes);
  if (!read.ok() && reader_.scan().malformed) {
    return InvalidArgument(
        fmt::format("a request on this connection (after frame {}) is not a valid "
                    "skinserve.v1.SkinRequest",
                    last_frame_read_ ? fmt::to_string(*last_frame_read_) : "none"));
  }
  const uint64_t frame = read.ok() ? reader_.request().frame() : reader_.scan().frame;
  last_frame_read_ = frame;
  if (read.ok() && reader_.request().characters_size() > 0) {  // a tick: tick_job.h
    TickJob& tick = ticks_.Take();
    if (!tick.Start(*reader_.mutable_request(), *access_.engine, access_.default_backend,
                    access_.regions)) {
      tick.set_done();  // answered already: no callback comes
    }
    reader_.Trim();
    End end = WriteAnswer(tick);
    ticks_.Recycle(&tick);
    return end;
  }
  if (!job_)
    job_ = std::make_unique<FrameJob>(static_cast<FrameJob::Listener*>(this), access_.budget);
  FrameJob& job = *job_;
  if (!read.ok()) {  // a limit: this frame fails, the connection goes on
    job.Refuse(frame, access_.default_backend, std::move(read));
    job.set_done();
    return WriteAnswer(job);
  }
  Status status = job.Prepare(*reader_.mutable_request(), *access_.engine, access_.default_backend,
                              access_.regions, &plan_);
  reader_.Trim();
  if (status.ok()) status = access_.engine->Run(&job);  // here, when a compute thread is free
  if (!status.ok()) {
    job.Fail(std::move(status));
    job.set_done();
  }
  return WriteAnswer(job);
}

void FrameSocketConnection::OnFrameDone(StreamAnswer* job) {
  {
    std::lock_guard lock(mutex_);
    job->set_done();
  }
  answered_.notify_one();
}

FrameSocketConnection::End FrameSocketConnection::WriteAnswer(StreamAnswer& answer) {
  {
    std::unique_lock lock(mutex_);
    answered_.wait(lock, [&] { return answer.done(); });
  }
  bool last = false;
  while (!last && answer.HasPartToSend()) {
    const grpc::ByteBuffer* part = answer.NextPart(&last);
    if (part == nullptr) break;
    const bool written = WriteMessage(*part, false);
    answer.PartWritten();
    if (!written) {
      client_gone_ = true;
      return Status(StatusCode::kCancelled, "the client went away");
    }
  }
  return std::nullopt;
}

bool FrameSocketConnection::WriteMessage(const grpc::ByteBuffer& message, bool end) {
  if (!message.Dump(&slices_).ok()) return false;
  unsigned char header[kHeaderBytes];
  wire::WriteFrameSocketHeader(
      static_cast<uint32_t>(message.Length()) | (end ? wire::kFrameSocketEndBit : 0), header);
  iov_.clear();
  iov_.push_back({header, kHeaderBytes});
  for (const grpc::Slice& slice : slices_) {
    if (iov_.size() == kMaxIovecs) {
      if (!SendAll(fd_, iov_.data(), iov_.size())) return false;
      iov_.clear();
    }
    iov_.push_back({const_cast<uint8_t*>(slice.begin()), slice.size()});
  }
  const bool sent = SendAll(fd_, iov_.data(), iov_.size());
  slices_.clear();  // the job's buffer is let go of before the job is reused
  return sent;
}

void FrameSocketConnection::SendEnd(const Status& status) {
  if (client_gone_) return;
  v1::SkinResponse end;
  end.set_frame(last_frame_read_.value_or(0));
  end.set_last(true);
  end.mutable_error()->set_code(wire::ToGrpc(status).error_code());
  end.mutable_error()->set_message(status.message());
  const std::string bytes = end.SerializeAsString();
  grpc::Slice slice(bytes.data(), bytes.size(), grpc::Slice::STATIC_SLICE);
  WriteMessage(grpc::ByteBuffer(&slice, 1), true);
  shutdown(fd_, SHUT_WR);
}

std::string FrameSocketConnection::QuietOrDrained(const char* what) const {
  return last_frame_read_ ? fmt::format(
                                "{}: every request read on this connection was answered (the last "
                                "was frame {}); send later frames on a new connection",
                                what, *last_frame_read_)
                          : fmt::format("{}; no request was read on this connection", what);
}

FrameSocketConnection::End FrameSocketConnection::Grow(std::size_t bytes) {
  const std::size_t want = std::max(bytes, kInitialBufferBytes);
  if (want <= buffer_.size()) return std::nullopt;
  if (Status s = access_.budget->TryCharge(want - charged_); !s.ok()) return s;
  charged_ = want;
  buffer_.resize(want);
  return std::nullopt;
}

FrameSocketConnection::End FrameSocketConnection::Fill(std::size_t bytes, bool at_boundary) {
  if (read_end_ - read_begin_ >= bytes) return std::nullopt;
  // Keep what is unread at the front, then make room for the rest.
  if (read_begin_ > 0) {
    std::memmove(buffer_.data(), buffer_.data() + read_begin_, read_end_ - read_begin_);
    read_end_ -= read_begin_;
    read_begin_ = 0;
  }
  if (End end = Grow(bytes)) return end;
  while (read_end_ < bytes) {
    // Waiting in poll, not in recv: recv's wait also wakes each time the client reads an
    // answer (the kernel wakes a Unix socket's sleepers when its sent bytes are consumed),
    // a second context switch a frame; poll's wait wakes only for bytes to read. Polled
    // first: after an answer the next request is rarely there yet, and a recv that finds
    // nothing would be one more system call a frame.
    pollfd readable = {fd_, POLLIN, 0};
    const int ready = poll(&readable, 1, idle_ms_);
    if (ready < 0 && errno == EINTR) continue;
    ssize_t got = -1;
    if (ready == 0) {
      errno = EAGAIN;  // quiet for --stream-idle-seconds
    } else if (ready > 0) {
      got = recv(fd_, buffer_.data() + read_end_, buffer_.size() - read_end_, MSG_DONTWAIT);
      if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) continue;  // woken for nothing
    }
    if (got > 0) {
      read_end_ += static_cast<std::size_t>(got);
      continue;
    }
    if (got < 0 && errno == EINTR) continue;
    if (draining_.load()) return Unavailable(QuietOrDrained("the server is shutting down"));
    if (got == 0 && at_boundary && read_end_ == 0) return Status::Ok();  // the client is done
    if (got == 0) {
      return InvalidArgument(fmt::format(
          "the connection closed in the middle of a message ({} of {} bytes)", read_end_, bytes));
    }
    if (errno == EAGAIN || errno == EWOULDBLOCK) {
      return Unavailable(QuietOrDrained(
          fmt::format("no request for {} s (--stream-idle-seconds)", idle_seconds_).c_str()));
    }
    client_gone_ = true;
    return Status(StatusCode::kCancelled,
                  fmt::format("the connection failed: {}", std::strerror(errno)));
  }
  return std::nullopt;
}

}  // namespace skinserve::server
