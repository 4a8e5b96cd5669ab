# Cross build for arm64 with Debian's cross toolchain (crossbuild-essential-arm64) against
# the arm64 packages of a multiarch install (dpkg --add-architecture arm64); the test
# binaries run under qemu-user. Used by scripts/arm64-test.sh.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# Debian's multiarch layout: find_package looks in /usr/lib/aarch64-linux-gnu first.
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# Multiarch libc6:arm64 and friends are what run: no -L (the cross toolchain's own
# libc is a different build, and threads hang when the two are mixed).
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64)
# Never the host's libraries: pkg-config (FindOpenSSL asks it first) and plain searches
# see only the arm64 ones.
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig)
set(CMAKE_IGNORE_PATH /usr/lib/x86_64-linux-gnu /lib/x86_64-linux-gnu)
# GCC's note that a C++17 ABI detail changed in GCC 10.1 concerns binaries mixed across
# that version, which this build never does.
set(CMAKE_CXX_FLAGS_INIT -Wno-psabi)
