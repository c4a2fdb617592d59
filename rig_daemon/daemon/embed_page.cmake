# cmake -DINPUT=page.html -DOUTPUT=page.cpp -P embed_page.cmake: the page as a C++ string (hex bytes,
# so no character of the page can end a literal early).
file(READ ${INPUT} _hex HEX)
string(LENGTH "${_hex}" _n)
math(EXPR _bytes "${_n} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "'\\\\x\\1'," _chars "${_hex}")
file(WRITE ${OUTPUT}
  "// Generated from ${INPUT} by embed_page.cmake; do not edit.\n"
  "#include \"rig_daemon/daemon/live_page.h\"\n\n"
  "namespace hc::rig {\nnamespace {\nconstexpr char kPage[] = {${_chars} '\\0'};\n}  // namespace\n\n"
  "std::string_view live_page_html() { return {kPage, ${_bytes}}; }\n\n}  // namespace hc::rig\n")
