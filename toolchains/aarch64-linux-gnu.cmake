# Cross build for arm64 (aarch64) robot computers running Debian bookworm, from an amd64
# Debian bookworm machine: Debian's g++-aarch64-linux-gnu against an arm64 sysroot made by
# toolchains/make-arm64-sysroot.sh, with test binaries run under qemu-aarch64-static.
#
# The sysroot is RANKSLAM_ARM64_SYSROOT (cache variable), else the environment variable of the
# same name, else /var/cache/rankslam/sysroot-arm64 (the script's default).
#
# Debian multiarch cannot serve here: the arm64 OpenCV and Ceres -dev packages are not
# co-installable with the amd64 ones the native build uses, hence a separate sysroot.

set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

if(NOT RANKSLAM_ARM64_SYSROOT)
  if(DEFINED ENV{RANKSLAM_ARM64_SYSROOT} AND NOT "$ENV{RANKSLAM_ARM64_SYSROOT}" STREQUAL "")
    set(RANKSLAM_ARM64_SYSROOT "$ENV{RANKSLAM_ARM64_SYSROOT}")
  else()
    set(RANKSLAM_ARM64_SYSROOT /var/cache/rankslam/sysroot-arm64)
  endif()
endif()
set(RANKSLAM_ARM64_SYSROOT "${RANKSLAM_ARM64_SYSROOT}" CACHE PATH
    "Debian bookworm arm64 sysroot (toolchains/make-arm64-sysroot.sh)" FORCE)
# try_compile projects re-read this file; hand them the same sysroot.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES RANKSLAM_ARM64_SYSROOT)

if(NOT EXISTS "${RANKSLAM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/cmake/opencv4/OpenCVConfig.cmake")
  message(FATAL_ERROR
    "No arm64 sysroot at ${RANKSLAM_ARM64_SYSROOT}: create it with toolchains/make-arm64-sysroot.sh "
    "(as root), or point RANKSLAM_ARM64_SYSROOT at an existing one.")
endif()

set(CMAKE_SYSROOT "${RANKSLAM_ARM64_SYSROOT}")
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

# Libraries, headers and CMake package configs come from the sysroot only; programs run during
# the build (pkg-config, protoc-like generators) are the build machine's.
set(CMAKE_FIND_ROOT_PATH "${RANKSLAM_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# Shared libraries' own dependencies (libopencv_* -> libgdal, libblas.so.3 ...) are resolved by
# the linker in the sysroot, not in the build machine's /usr/lib.
set(_rankslam_rpath_link
    "-Wl,-rpath-link,${RANKSLAM_ARM64_SYSROOT}/lib/aarch64-linux-gnu"
    "-Wl,-rpath-link,${RANKSLAM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu")
list(JOIN _rankslam_rpath_link " " _rankslam_rpath_link)
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_rankslam_rpath_link}")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "${_rankslam_rpath_link}")
set(CMAKE_MODULE_LINKER_FLAGS_INIT "${_rankslam_rpath_link}")

# pkg-config (FindPkgConfig) reads the sysroot's .pc files and prefixes their paths with it.
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${RANKSLAM_ARM64_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
    "${RANKSLAM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${RANKSLAM_ARM64_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# ctest and gtest_discover_tests run the arm64 binaries through qemu. No binfmt_misc is assumed,
# so the emulator is named explicitly; -L makes the dynamic loader and every library come from
# the sysroot (the cross toolchain's /usr/aarch64-linux-gnu has a different libc build and is
# not a substitute).
find_program(RANKSLAM_QEMU_AARCH64 qemu-aarch64-static)
if(NOT RANKSLAM_QEMU_AARCH64)
  message(FATAL_ERROR "qemu-aarch64-static not found: apt-get install qemu-user-static "
                      "(toolchains/make-arm64-sysroot.sh installs it)")
endif()
set(CMAKE_CROSSCOMPILING_EMULATOR "${RANKSLAM_QEMU_AARCH64};-L;${RANKSLAM_ARM64_SYSROOT}")
