#pragma once
// Whitespace-separated tokens of a mesh file with their line numbers, for error messages that
// name the file and the line ("ball.msh:17: expected a node id, found 'x'"). Start-up only.
#include <cstdint>
#include <string>
#include <string_view>

#include "firmware/scene/mesh_io.hpp"

namespace haptic::scene {

class TextCursor {
 public:
  // `comment`: a character that starts a comment running to the end of the line (0: none).
  TextCursor(const std::string& text, std::string file, char comment = 0) : text_(text), file_(std::move(file)), comment_(comment) {}

  bool at_end();                               // skips blanks and comments first
  std::string_view token(const char* what);    // throws at the end of the file
  long long integer(const char* what);         // a whole token that is an integer
  double real(const char* what);               // a whole token that is a finite number
  std::string_view line_rest();                // the rest of the current line (trimmed); moves past it
  void expect(std::string_view word);          // the next token must be `word`
  int line() const { return token_line_; }     // line of the last token read (1-based)
  [[noreturn]] void fail(const std::string& msg) const { fail_at(token_line_, msg); }
  [[noreturn]] void fail_at(int line, const std::string& msg) const;
  const std::string& file() const { return file_; }

 private:
  void skip_blanks();
  const std::string& text_;
  std::string file_;
  char comment_;
  std::size_t pos_ = 0;
  int line_ = 1;
  int token_line_ = 1;
};

}  // namespace haptic::scene
