# Writes OUT, a C++ source holding the bytes of IN as rankslam_built_in_vocabulary (empty when IN
# is absent: the program then reports that it has no built-in vocabulary).
if(EXISTS "${IN}")
  file(READ "${IN}" hex HEX)
else()
  set(hex "")
endif()
string(LENGTH "${hex}" digits)
math(EXPR size "${digits} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
string(REGEX REPLACE "((0x..,){32})" "\\1\n" bytes "${bytes}")
file(WRITE "${OUT}.tmp" "#include <cstddef>\n// Generated from ${IN}.\nextern \"C\" const unsigned char rankslam_built_in_vocabulary[];\nextern \"C\" const std::size_t rankslam_built_in_vocabulary_size;\nextern \"C\" const unsigned char rankslam_built_in_vocabulary[] = {\n${bytes}0};\nextern \"C\" const std::size_t rankslam_built_in_vocabulary_size = ${size};\n")
file(COPY_FILE "${OUT}.tmp" "${OUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUT}.tmp")
