// The journal's records (format: service/journal.hpp) made and replayed, for every
// SessionStorage: the records a change writes, the step files an undo or redo keeps, and the
// replay of a snapshot's records into a Session.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "service/session.hpp"

namespace marzipan::service {

// The record of a stroke's start: tool, radius, strength, symmetry, accumulate, height, and what it
// applied so far (its memory), which recovery reads back; of a paint or mask stroke the same
// without a height, with hardness, color ([r, g, b], paint) and erase (true for a mask stroke
// that erases); of a warp stroke: tool, radius,
// strength, volume, direction, and once it has an anchor "warp": its state (anchor, normal,
// pointer, held, held_amount; apply_op.hpp WarpStroke), from which it goes on. The hub writes it at stroke.begin and
// at the head of every new journal for the strokes still open.
nlohmann::json strokeBeginRecord(StrokeId id, const Session::StrokeParams& st);
// A stroke's plane as the journal and the replies write it: {"point":[x,y,z],"normal":[x,y,z]}.
nlohmann::json planeJson(const Plane& plane);

// Adds who made a step ("by", when the author has an id or a name) and when ("t") to the
// record of a change: an op, a stroke message or a load (see service/journal.hpp).
void stampRecord(nlohmann::json& record, const StepAuthor& by, std::int64_t timeMs);
// The record of an undoMine/redoMine that moved `step` to revision `revision`; `file` is what
// saveStep() returned for the bricks it put in place (HistoryResult::restored).
nlohmann::json authorMoveRecord(bool undo, std::uint64_t revision, const std::string& file, const StepInfo& step);

// The bricks an undo or redo put in place, as a step file: "MZBK", u32 count, per brick i32 x y
// z, u8 0 outside / 1 inside / 2 data + 512 f32 / 3 data + 512 f32 + its channels, 512 texels of
// u8 R, G, B, mask (index as the floats; a brick without channels is kind 2, so files of
// unpainted sessions are what they were), then the CRC-32 of all before it; little-endian.
std::vector<std::uint8_t> encodeStep(const std::vector<std::pair<Int3, BrickRef>>& bricks);
// Throws std::runtime_error("unreadable step file NAME") when the bytes are not one.
std::vector<std::pair<Int3, BrickRef>> decodeStep(std::span<const std::uint8_t> bytes, const std::string& name);

// Replays records in journal order into a session recovered from its snapshot.
class Replay {
 public:
  // readFile(name): the bytes of a file a record names ({"undo"/"redo"/"load": name}).
  Replay(Session& session, std::function<std::vector<std::uint8_t>(const std::string& name)> readFile, ThreadPool& pool)
      : session_(session), readFile_(std::move(readFile)), pool_(pool) {}
  // Throws std::runtime_error when a record is unknown or its revision disagrees with the
  // session's after it, or an undo_mine/redo_mine moved through the history puts other bricks
  // in place than its file holds.
  void apply(const nlohmann::json& record);
  // Ends the strokes the records left open (their clients are gone).
  void finish();

 private:
  Session& session_;
  std::function<std::vector<std::uint8_t>(const std::string&)> readFile_;
  ThreadPool& pool_;
  std::map<std::uint64_t, StrokeId> strokes_;  // journal stroke id -> the session's
};

}  // namespace marzipan::service
