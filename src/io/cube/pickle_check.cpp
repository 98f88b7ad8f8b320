// Opcodes and stack effects as LibTorch 1.13's Unpickler::readInstruction
// has them (torch/csrc/jit/serialization/unpickler.cpp).
#include "io/cube/pickle_check.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/files/little_endian.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

class PickleWalk {
 public:
  PickleWalk(const char* pickle, size_t size, const fs::path& path)
      : pickle_(pickle), size_(size), path_(path) {}

  void run() {
    // PROTO 2 first, or LibTorch refuses the pickle.
    if (size_ < 2 || uint8_t(pickle_[0]) != 0x80) return;
    for (pos_ = 2; pos_ < size_;) {
      at_ = pos_;
      const uint8_t opcode = uint8_t(pickle_[pos_++]);
      if (opcode == '.' || !step(opcode)) return;  // STOP, or one LibTorch refuses
    }
  }

 private:
  // The stack effect of one opcode; false for one LibTorch does not know.
  bool step(uint8_t opcode) {
    switch (opcode) {
      case '(':  // MARK
        marks_.push_back(depth_);
        return true;
      // Constants: EMPTY_TUPLE, NONE, EMPTY_LIST, EMPTY_DICT, NEWTRUE, NEWFALSE.
      case ')':
      case 'N':
      case ']':
      case '}':
      case 0x88:
      case 0x89:
        return push(0);
      // BININT1, BINGET.
      case 'K':
      case 'h':
        return push(1);
      case 'M':  // BININT2
        return push(2);
      // BININT, LONG_BINGET.
      case 'J':
      case 'j':
        return push(4);
      case 'G':  // BINFLOAT
        return push(8);
      case 0x8a:  // LONG1: LibTorch reads 8 bytes after the length byte
        return push(9);
      case 'X':  // BINUNICODE
        return push(4 + string_length());
      case 'c':  // GLOBAL: module and name, one line each
        skip_line();
        skip_line();
        return push(0);
      // BINPUT, LONG_BINPUT: memoize the top under an index.
      case 'q':
        memoize(1, opcode);
        return pops(1, 1, 1, opcode);
      case 'r':
        memoize(4, opcode);
        return pops(1, 1, 4, opcode);
      case 'Q':  // BINPERSID: a tuple for a storage
        return pops(1, 1, 0, opcode);
      case 0x81:  // NEWOBJ: drops the top
        return pops(1, 0, 0, opcode);
      case 0x85:  // TUPLE1
        return pops(1, 1, 0, opcode);
      case 0x86:  // TUPLE2
        return pops(2, 1, 0, opcode);
      case 0x87:  // TUPLE3
        return pops(3, 1, 0, opcode);
      // REDUCE, BUILD: a callable and its argument for one result.
      case 'R':
      case 'b':
        return pops(2, 1, 0, opcode);
      // TUPLE, LIST: the values above the mark.
      case 't':
      case 'l':
        depth_ = pop_mark(opcode) + 1;
        return true;
      // DICT, SETITEMS: key-value pairs above the mark (SETITEMS: into the
      // dictionary below it).
      case 'd':
      case 'u': {
        const size_t mark = pop_mark(opcode);
        if ((depth_ - mark) % 2 != 0) fail(opcode, "an odd number of keys and values");
        if (opcode == 'u' && mark == 0) fail(opcode, "no dictionary below its mark");
        depth_ = opcode == 'd' ? mark + 1 : mark;
        return true;
      }
      case 'e': {  // APPENDS: the values above the mark onto the list below it
        const size_t mark = pop_mark(opcode);
        if (mark == 0) fail(opcode, "no list below its mark");
        depth_ = mark;
        return true;
      }
      default:
        return false;
    }
  }

  // An opcode that takes `taken` values off the stack (checked) and puts
  // `given` back, after `argument_bytes` of argument.
  bool pops(size_t taken, size_t given, size_t argument_bytes, uint8_t opcode) {
    if (depth_ < taken)
      fail(opcode, "takes " + std::to_string(taken) + " value(s), the stack holds " +
                       std::to_string(depth_));
    depth_ = depth_ - taken + given;
    pos_ += argument_bytes;
    return true;
  }

  // LibTorch grows its memo table to the index given: a pickler numbers
  // entries in order, so an index past the next free one is corrupt (one of
  // 1.2e9 made LibTorch allocate 18.8 GB).
  void memoize(size_t index_bytes, uint8_t opcode) {
    const uint64_t index = little_endian({pickle_, size_}, pos_, index_bytes);
    if (index > memo_size_)
      fail(opcode, "memo index " + std::to_string(index) + " past the " +
                       std::to_string(memo_size_) + " entries so far");
    memo_size_ = std::max<uint64_t>(memo_size_, index + 1);
  }

  bool push(size_t argument_bytes) {
    pos_ += argument_bytes;
    ++depth_;
    return true;
  }

  // BINUNICODE's 4-byte little-endian length, checked against what is left.
  size_t string_length() {
    const uint64_t length = little_endian({pickle_, size_}, pos_, 4);
    const size_t left = size_ - std::min(size_, pos_ + 4);
    if (length > left)
      throw core::Error(path_, "corrupt torch.save pickle: a string of " + std::to_string(length) +
                                   " bytes at byte " + std::to_string(at_) + ", only " +
                                   std::to_string(left) + " bytes follow");
    return size_t(length);
  }

  void skip_line() {
    if (pos_ >= size_) return;
    const void* end = std::memchr(pickle_ + pos_, '\n', size_ - pos_);
    pos_ = end ? size_t(static_cast<const char*>(end) - pickle_) + 1 : size_;
  }

  size_t pop_mark(uint8_t opcode) {
    if (marks_.empty()) fail(opcode, "no mark");
    const size_t mark = marks_.back();
    marks_.pop_back();
    if (mark > depth_) fail(opcode, "a mark above the stack");
    return mark;
  }

  [[noreturn]] void fail(uint8_t opcode, const std::string& problem) const {
    char name[8];
    std::snprintf(name, sizeof name, "0x%02x", opcode);
    throw core::Error(path_, "corrupt torch.save pickle: opcode " + std::string(name) +
                                 " at byte " + std::to_string(at_) + ": " + problem);
  }

  const char* pickle_;
  size_t size_;
  const fs::path& path_;
  size_t pos_ = 0;
  size_t at_ = 0;  // where the current opcode starts
  size_t depth_ = 0;
  uint64_t memo_size_ = 0;  // memo entries so far
  std::vector<size_t> marks_;
};

}  // namespace

void check_pickle(const char* pickle, size_t size, const fs::path& path) {
  PickleWalk(pickle, size, path).run();
}

}  // namespace ddhgs::io::detail
