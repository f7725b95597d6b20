# The relighting page's browser test serves the page from cpp-httplib (Debian's
# libcpp-httplib-dev is a compiled library, found through pkg-config).
find_package(PkgConfig REQUIRED)
pkg_check_modules(RIG_HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
target_link_libraries(rig_view_command_test PRIVATE PkgConfig::RIG_HTTPLIB)
