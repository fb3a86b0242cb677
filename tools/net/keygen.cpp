// haptic-keygen FILE...: creates each FILE (mode 0600, never overwriting) holding a fresh station
// key pair (libsodium crypto_kx) and prints "FILE <public key hex>" per line, for the lab file's
// [[net.peers]] public_key entries. Exit 0 on success, 1 when a file cannot be created, 2 on usage.
#include <cstdio>
#include <cstring>
#include <exception>

#include "net/keys.hpp"
#include "platform/command_line.hpp"

int main(int argc, char** argv) {
  if (argc == 2 && std::strcmp(argv[1], "--version") == 0) {
    std::printf("%s\n", haptic::platform::version_line("haptic-keygen").c_str());
    return 0;
  }
  // An option-looking argument is a mistyped option, never a file name to create.
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.size() > 1 && arg[0] == '-' && arg != "--help" && arg != "-h") {
      const std::string near = haptic::platform::nearest(arg, {"--help", "--version"});
      std::fprintf(stderr, "haptic-keygen: error: unknown option %s%s%s%s (a key file name cannot start with '-'; write ./%s)\n", arg.c_str(),
                   near.empty() ? "" : " (did you mean ", near.c_str(), near.empty() ? "" : "?)", arg.c_str());
      return 2;
    }
  }
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::fprintf(argc < 2 ? stderr : stdout,
                 "usage: haptic-keygen FILE...\n"
                 "Creates each FILE (mode 0600; an existing file is never overwritten) with a fresh station key\n"
                 "pair (public_key, secret_key; libsodium crypto_kx) and prints 'FILE PUBLIC_KEY_HEX' per line.\n"
                 "A station reads its own file via net.key_file; its neighbours list the public key as\n"
                 "[[net.peers]] public_key. --version prints the build. Exit status: 0 ok, 1 a file could not be created, 2 usage.\n");
    return argc < 2 ? 2 : 0;
  }
  for (int i = 1; i < argc; ++i) {
    try {
      std::printf("%s %s\n", argv[i], haptic::net::write_new_key_file(argv[i]).c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "haptic-keygen: %s\n", e.what());
      return 1;
    }
  }
  return 0;
}
