// How many times reading a client's .vdb upload copies it: the bytes OpenVDB is shown are cut
// once from the upload, in memory; the upload itself is neither copied into a string nor into
// an istringstream on the way. Counted with this test binary's own operator new (below): blocks
// of about the file's size are copies of it, or OpenVDB's own, counted apart by reading the
// same bytes through it directly. Before, the hub's upload took four: the payload cut from the
// frame, the stream read into a string, the cut for OpenVDB, and the istringstream's copy.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdlib>
#include <new>
#include <optional>
#include <span>
#include <sstream>
#include <streambuf>
#include <string>

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include "engine/measures.hpp"
#include "engine/openvdb/vdb_io.hpp"
#include "engine/solids.hpp"

namespace {

// Blocks of tBig to 1.5 tBig bytes allocated by this thread while tBig > 0.
thread_local std::size_t tBig = 0;
thread_local int tBigBlocks = 0;

void* allocate(std::size_t n) {
  if (tBig > 0 && n >= tBig && n < tBig + tBig / 2) ++tBigBlocks;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}

// Counts the blocks of the file's size `f` allocates (up to 1.5 times it: a copy grown by
// doubling counts too; OpenVDB's tables and the volume's brick pools are larger here).
template <class F>
int bigBlocks(std::size_t atLeast, F f) {
  tBigBlocks = 0;
  tBig = atLeast;
  f();
  tBig = 0;
  return tBigBlocks;
}

// A stream over bytes held elsewhere (the reference read copies nothing either).
struct View : std::streambuf {
  explicit View(const std::string& s) {
    char* p = const_cast<char*>(s.data());
    setg(p, p, p + s.size());
  }
};

}  // namespace

void* operator new(std::size_t n) { return allocate(n); }
void* operator new[](std::size_t n) { return allocate(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace marzipan;

TEST_CASE("a .vdb upload in memory is copied once on its way to OpenVDB", "[openvdb]") {
  openvdb::initialize();
  const Volume pig = makeSolid(SolidKind::Pig, {72, 64, 56});
  std::ostringstream out(std::ios::binary);
  saveVdb(pig, out);
  const std::string file = std::move(out).str();
  const std::size_t big = file.size();
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(file.data()), file.size());
  // OpenVDB's own big blocks for this grid, read straight from the bytes.
  const int openvdbOwn = bigBlocks(big, [&] {
    View view(file);
    std::istream in(&view);
    REQUIRE(openvdb::io::Stream(in, false).getGrids()->size() == 1);
  });
  std::optional<Volume> read;
  const int loading = bigBlocks(big, [&] { read.emplace(loadVdb(bytes, pig.dims())); });
  CHECK(digest(*read) == digest(pig));
  INFO("file " << file.size() << " bytes, OpenVDB's own blocks of its size " << openvdbOwn);
  CHECK(loading - openvdbOwn == 1);
  // The stream form must read the stream into memory first: one copy more.
  const int fromStream = bigBlocks(big, [&] {
    std::istringstream in(file, std::ios::binary);
    read.emplace(loadVdb(in, pig.dims()));
  });
  CHECK(fromStream - openvdbOwn == 3);  // the istringstream's own copy, the file read from it, the cut
}
