#include "firmware/scene/text_cursor.hpp"

#include <charconv>
#include <cmath>
#include <cstdlib>

namespace haptic::scene {

void TextCursor::fail_at(int line, const std::string& msg) const { throw MeshError(file_ + ":" + std::to_string(line) + ": " + msg); }

void TextCursor::skip_blanks() {
  while (pos_ < text_.size()) {
    const char c = text_[pos_];
    if (c == '\n') {
      ++line_;
      ++pos_;
    } else if (c == ' ' || c == '\t' || c == '\r') {
      ++pos_;
    } else if (comment_ != 0 && c == comment_) {
      while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    } else {
      return;
    }
  }
}

bool TextCursor::at_end() {
  skip_blanks();
  return pos_ >= text_.size();
}

std::string_view TextCursor::token(const char* what) {
  skip_blanks();
  token_line_ = line_;
  if (pos_ >= text_.size()) fail(std::string("expected ") + what + ", found the end of the file");
  const std::size_t start = pos_;
  while (pos_ < text_.size() && text_[pos_] != ' ' && text_[pos_] != '\t' && text_[pos_] != '\r' && text_[pos_] != '\n' &&
         (comment_ == 0 || text_[pos_] != comment_))
    ++pos_;
  return std::string_view(text_).substr(start, pos_ - start);
}

long long TextCursor::integer(const char* what) {
  const std::string_view t = token(what);
  long long v = 0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || end != t.data() + t.size()) fail(std::string("expected ") + what + " (an integer), found '" + std::string(t) + "'");
  return v;
}

double TextCursor::real(const char* what) {
  const std::string_view t = token(what);
  const std::string s(t);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || !std::isfinite(v)) fail(std::string("expected ") + what + " (a finite number), found '" + s + "'");
  return v;
}

std::string_view TextCursor::line_rest() {
  while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\t')) ++pos_;
  token_line_ = line_;
  const std::size_t start = pos_;
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  std::size_t end = pos_;
  while (end > start && (text_[end - 1] == '\r' || text_[end - 1] == ' ' || text_[end - 1] == '\t')) --end;
  if (pos_ < text_.size()) {
    ++pos_;
    ++line_;
  }
  return std::string_view(text_).substr(start, end - start);
}

void TextCursor::expect(std::string_view word) {
  const std::string_view t = token(std::string(word).c_str());
  if (t != word) fail("expected '" + std::string(word) + "', found '" + std::string(t) + "'");
}

}  // namespace haptic::scene
