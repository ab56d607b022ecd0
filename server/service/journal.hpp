// A session's journal: every acknowledged change, appended before its response is sent, so
// that the last snapshot plus the journal gives back exactly the last acknowledged revision.
//
// Format: text, one record per line: 8 lower-case hex digits of the CRC-32 (IEEE) of the JSON
// that follows, one space, one JSON object, "\n". Records (R = the revision after the change;
// S = the session's stroke id; positions in vu, already resolved: a ray's hit, not the ray):
//   {"r":R,"op":{...}}                       tool.apply / volume.morph: the canonical op object
//   {"r":R,"stroke":S,"dabs":[[x,y,z,p(,nx,ny,nz)],...]} stroke.dabs: the centres that applied,
//                                          pressure p, and in a stroke with a height the normal
//                                          each was anchored along; [,"plane":{"point":[x,y,z],
//                                          "normal":[x,y,z]}] once the stroke has one (flatten,
//                                          contrast, clay with a height: Session::beginStroke)
//   {"stroke_begin":S,"tool":T,"radius":r,"strength":s,"symmetry":"xz"[,"accumulate":true]
//    [,"height":h][,"applied":[[x,y,z,w(,nx,ny,nz)],...]][,"plane":{...}]}
//                                          "applied": the dab images an open stroke had applied
//                                            (its memory), "plane" its plane, when re-announced
//                                            after a snapshot
//   {"stroke_begin":S,"tool":W,"radius":r,"strength":s[,"volume":v][,"direction":[x,y,z]]
//    [,"warp":{"anchor":[..],"normal":[..],"held":[..],"held_amount":a[,"pointer":[..]]}]}
//                                          a warp stroke (PROTOCOL.md, warp strokes); "warp": its
//                                            state when re-announced after a snapshot, from whose
//                                            volume it goes on (service/apply_op.hpp WarpStroke).
//                                            Its "stroke" records hold its dabs as given (the
//                                            anchor first; pressure p: pinch_path's), and the record of
//                                            the message that took the anchor has the same R as
//                                            the record before it when it changed nothing
//   {"stroke_end":S}
//   {"r":R,"undo":"step-R.bin"}  {"r":R,"redo":"step-R.bin"}: the bricks it put in place, for a
//                                            replay whose history lost the step to a snapshot
//   {"r":R,"load":"load-R.mzv"}              volume.load: the file, stored beside the journal
//   {"r":R,"undo_mine":"step-R.bin","by":{"id":I,"name":N},"step":[F,L]}  (and "redo_mine"):
//                                            undo/redo of author I's own step, the one whose
//                                            changes made revisions F..L; the file as for undo
// Optional on "op", "stroke", "load" and "stroke_begin" records: "by":{"id":I,"name":N}, who
// made the step (stroke_begin: who makes the stroke's steps), and "t": its wall-clock time in
// ms since the Unix epoch, so that replay rebuilds the steps' authors and times (history.list,
// undo mine). Records without them replay as steps of nobody, timed at the replay.
// Stroke begin/end records change no revision; they are kept so that replay folds dabs into
// the same undo steps as the original.
// A line that is cut short or fails its CRC ends the journal: a crash can only tear the last
// record, which was never acknowledged; reading truncates the file there.
// Durability: with syncEach every append is fsynced before it returns; otherwise at most every
// syncInterval (and on close), so a crash may lose that much acknowledged work.
#pragma once

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace marzipan::service {

class Journal {
 public:
  // Opens (creating if missing) for appending. Throws std::runtime_error naming the path.
  Journal(std::filesystem::path path, std::chrono::milliseconds syncInterval);
  ~Journal();
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;

  // Appends one record; throws std::runtime_error (with the system's reason: "No space left
  // on device") when it cannot be written or synced; the file is then cut back to where it
  // was, so the refused record is not replayed.
  void append(const nlohmann::json& record);
  void sync();
  // Appended records not yet synced (with a sync interval): the owner's timer calls sync().
  bool dirty() const { return dirty_; }
  std::size_t records() const { return records_; }
  const std::filesystem::path& path() const { return path_; }

  // The valid records of a journal file, in order. A torn or corrupt line and everything after
  // it are dropped and, when truncate is set, cut from the file; `warn` hears of it.
  static std::vector<nlohmann::json> read(const std::filesystem::path& path, bool truncate,
                                          const std::function<void(const std::string&)>& warn);

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::chrono::milliseconds syncInterval_;
  std::chrono::steady_clock::time_point lastSync_;
  bool dirty_ = false;
  std::size_t records_ = 0;
};

// The line of one record (CRC, space, JSON, newline).
std::string journalLine(const nlohmann::json& record);

// Writes all of bytes to fd (retrying short writes and EINTR); throws std::runtime_error
// "cannot write PATH: reason" naming `path`.
void writeAll(int fd, std::string_view bytes, const std::filesystem::path& path);

}  // namespace marzipan::service
