#include "frames/tick_job.h"

#include <fmt/format.h>
#include <grpcpp/impl/codegen/proto_utils.h>

#include <algorithm>

#include "observability/metrics_frames.h"
#include "rpc/server_messages.h"

namespace skinserve::server {
namespace {

// The first field of `request` that is set, other than `frame` and `characters` (a tick's
// own fields); null if none. Walks the descriptor: a field added later is covered too.
const google::protobuf::FieldDescriptor* FirstOwnFieldSet(const v1::SkinRequest& request) {
  const google::protobuf::Descriptor* d = request.GetDescriptor();
  const google::protobuf::Reflection* r = request.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const google::protobuf::FieldDescriptor* f = d->field(i);
    if (f->number() == v1::SkinRequest::kFrameFieldNumber ||
        f->number() == v1::SkinRequest::kCharactersFieldNumber) {
      continue;
    }
    if (f->is_repeated() ? r->FieldSize(request, f) > 0 : r->HasField(request, f)) return f;
  }
  return nullptr;
}

// A character's fields that belong to the tick: INVALID_ARGUMENT naming the first set.
Status CheckCharacterFields(const v1::SkinRequest& character) {
  const char* field = character.frame() != 0            ? "frame"
                      : character.early_parts()         ? "early_parts"
                      : character.characters_size() > 0 ? "characters"
                                                        : nullptr;
  if (field == nullptr) return Status::Ok();
  return InvalidArgument(
      fmt::format("{} is set; a tick's characters leave it unset (frame is the tick's, early_parts "
                  "is implied, ticks do not nest)",
                  field));
}

}  // namespace

TickJob::~TickJob() { DropWire(); }

bool TickJob::Start(v1::SkinRequest& request, Engine& engine, const std::string& default_backend,
                    const RegionCaller& regions) {
  frame_ = request.frame();
  count_ = static_cast<uint32_t>(request.characters_size());
  status_ = Status::Ok();
  done_ = false;
  error_part_ = false;
  final_ready_ = final_handed_out_ = false;
  finished_ = next_sending_ = 0;
  writing_ = nullptr;
  CountTick(count_);
  if (const auto* own = FirstOwnFieldSet(request)) {
    FailTick(InvalidArgument(fmt::format(
        "the request is a tick (characters set) but its own field {} is set too: a tick carries "
        "only frame and characters; set {} on each character instead",
        own->name(), own->name())));
    return false;
  }
  while (characters_.size() < count_) {
    characters_.push_back(
        std::make_unique<FrameJob>(static_cast<FrameJob::Listener*>(this), budget_));
  }
  while (character_plans_.size() < count_)
    character_plans_.push_back(std::make_unique<StreamPlan>());
  if (order_.size() < count_) order_.resize(count_);
  pending_.store(count_ + 1);
  // Every character prepared first, then all submitted: the compute threads take them side
  // by side.
  for (uint32_t i = 0; i < count_; ++i) {
    characters_[i]->SetTickCharacter(i, frame_);
    if (!PrepareCharacter(i, *request.mutable_characters(static_cast<int>(i)), engine,
                          default_backend, regions)) {
      characters_[i]->set_done();
      CharacterDone(i);  // never the last: Start holds one
    }
  }
  // One place in the engine's queue for the whole tick (Engine::SubmitGroup).
  group_.jobs.clear();
  submitted_.clear();
  for (uint32_t i = 0; i < count_; ++i) {
    if (characters_[i]->done()) continue;  // failed before the engine
    group_.jobs.push_back(characters_[i].get());
    submitted_.push_back(i);
  }
  verdicts_.resize(group_.jobs.size());
  engine.SubmitGroup(&group_, verdicts_);
  for (std::size_t k = 0; k < submitted_.size(); ++k) {
    if (verdicts_[k].ok()) continue;
    FrameJob& job = *characters_[submitted_[k]];
    job.Fail(std::move(verdicts_[k]));
    job.set_done();
    CharacterDone(submitted_[k]);
  }
  if (pending_.fetch_sub(1) != 1) return true;  // the last character's callback finishes it
  BuildFinalPart();
  return false;
}

bool TickJob::PrepareCharacter(uint32_t i, v1::SkinRequest& character, Engine& engine,
                               const std::string& default_backend, const RegionCaller& regions) {
  FrameJob& job = *characters_[i];
  const std::string& backend = character.backend().empty() ? default_backend : character.backend();
  if (Status s = CheckCharacterFields(character); !s.ok()) {
    job.Refuse(frame_, backend, std::move(s));
    return false;
  }
  if (Status s =
          job.Prepare(character, engine, default_backend, regions, character_plans_[i].get());
      !s.ok()) {
    job.Fail(std::move(s));
    return false;
  }
  return true;
}

void TickJob::FailTick(Status status) {
  status_ = std::move(status);
  v1::SkinResponse part;
  part.set_frame(frame_);
  part.set_last(true);
  part.mutable_error()->set_code(ToGrpc(status_).error_code());
  part.mutable_error()->set_message(status_.message());
  bool own = false;
  error_bytes_.Clear();
  (void)grpc::SerializationTraits<v1::SkinResponse>::Serialize(part, &error_bytes_, &own);
  std::lock_guard lock(mutex_);
  error_part_ = true;
  final_ready_ = true;
}

void TickJob::CharacterDone(uint32_t i) {
  {
    std::lock_guard lock(mutex_);
    order_[finished_++] = i;
  }
  pending_.fetch_sub(1);
}

void TickJob::OnFrameDone(StreamAnswer* answer) {
  auto* character = static_cast<FrameJob*>(answer);
  character->set_done();
  const auto i = static_cast<uint32_t>(character->tick_character());
  {
    std::lock_guard lock(mutex_);
    order_[finished_++] = i;
  }
  // Told while this character still holds the tick (and so the listener) alive.
  listener_->OnPartsReady(this);
  if (pending_.fetch_sub(1) != 1) return;
  BuildFinalPart();
  listener_->OnFrameDone(this);  // may reuse this job at once: nothing after
}

void TickJob::SignalGpuRegions() {
  signalled_.clear();  // keeps its capacity
  for (uint32_t i = 0; i < count_; ++i) {
    std::shared_ptr<GpuRegion> region = characters_[i]->TakeGpuRegion();
    if (region == nullptr) continue;
    auto it = std::find_if(signalled_.begin(), signalled_.end(),
                           [&](const auto& s) { return s.first == region; });
    if (it == signalled_.end()) {
      const Status written = region->FrameWritten(frame_);
      it = signalled_.insert(signalled_.end(), {std::move(region), written});
    }
    if (!it->second.ok()) characters_[i]->FailWritten(it->second);
  }
  signalled_.clear();  // an unregister waiting for the tick may answer from here
}

void TickJob::BuildFinalPart() {
  SignalGpuRegions();
  final_.Clear();  // keeps the headers' objects for the next tick
  final_.set_frame(frame_);
  final_.set_last(true);
  auto* headers = final_.mutable_tick()->mutable_characters();
  for (uint32_t i = 0; i < count_; ++i) characters_[i]->TickHeader(headers->Add());
  final_bytes_.resize(final_.ByteSizeLong());
  final_.SerializeWithCachedSizesToArray(reinterpret_cast<uint8_t*>(final_bytes_.data()));
  std::lock_guard lock(mutex_);
  final_ready_ = true;
}

FrameJob* TickJob::SendingLocked() {
  while (next_sending_ < finished_) {
    FrameJob* job = characters_[order_[next_sending_]].get();
    if (job->status().ok() && !job->answers_in_region() && job->HasPartToSend()) return job;
    ++next_sending_;  // nothing (more) of it to send
  }
  return nullptr;
}

bool TickJob::HasPartToSend() {
  std::lock_guard lock(mutex_);
  if (error_part_) return !final_handed_out_;
  return SendingLocked() != nullptr || (final_ready_ && !final_handed_out_);
}

const grpc::ByteBuffer* TickJob::NextPart(bool* last) {
  std::lock_guard lock(mutex_);
  if (!error_part_) {
    if (FrameJob* job = SendingLocked()) {
      bool character_last = false;
      const grpc::ByteBuffer* part = job->NextPart(&character_last);
      if (part == nullptr) return nullptr;
      if (character_last) ++next_sending_;
      writing_ = job;
      *last = false;
      return part;
    }
  }
  if (!final_ready_ || final_handed_out_) return nullptr;
  final_handed_out_ = true;
  *last = true;
  writing_ = nullptr;
  if (error_part_) return &error_bytes_;
  // gRPC reads final_bytes_ in place: hold the listener until it lets go.
  final_refs_.store(1, std::memory_order_release);
  listener_->HoldForWire();
  grpc::Slice slice(final_bytes_.data(), final_bytes_.size(), &TickJob::FinalReleased, this);
  final_out_.emplace(&slice, 1);
  return &*final_out_;
}

void TickJob::PartWritten() {
  if (writing_ != nullptr) {
    writing_->PartWritten();
    writing_ = nullptr;
  } else {
    final_out_.reset();
  }
}

void TickJob::DropWire() {
  for (auto& character : characters_) character->DropWire();
  final_out_.reset();
}

bool TickJob::wire_in_use() const {
  if (final_refs_.load(std::memory_order_acquire) > 0) return true;
  for (const auto& character : characters_) {
    if (character->wire_in_use()) return true;
  }
  return false;
}

void TickJob::FinalReleased(void* job) {
  auto* self = static_cast<TickJob*>(job);
  FrameJob::Listener* listener = self->listener_;
  self->final_refs_.store(0, std::memory_order_release);  // the job may be reused from here
  listener->ReleaseForWire();
}

TickJob& TickJobs::Take() {
  for (auto it = idle_.rbegin(); it != idle_.rend(); ++it) {
    if (!(*it)->wire_in_use()) {
      TickJob* job = *it;
      idle_.erase(std::next(it).base());
      return *job;
    }
  }
  jobs_.push_back(std::make_unique<TickJob>(listener_, budget_));
  return *jobs_.back();
}

bool TickJobs::Recycle(StreamAnswer* answer) {
  if (!answer->is_tick()) return false;
  idle_.push_back(static_cast<TickJob*>(answer));
  return true;
}

void TickJobs::DropWire() {
  for (auto& job : jobs_) job->DropWire();
}

}  // namespace skinserve::server
