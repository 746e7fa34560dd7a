# Cross-compile for 64-bit ARM Linux (Raspberry Pi 4/5, Jetson, most companion computers).
# Compiler and sysroot only (the PX4 habit); tests run under qemu-aarch64 from ctest.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu /usr/lib/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64;-L;/usr/aarch64-linux-gnu)
# Header-only packages from the build machine's Debian, named explicitly so the root-path rules above
# do not hide them.
set(Eigen3_DIR /usr/share/eigen3/cmake CACHE PATH "")
set(Catch2_DIR /usr/lib/cmake/Catch2 CACHE PATH "")
