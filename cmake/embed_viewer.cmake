# The relighting page (process/export/viewer/) embedded by cmake/embed_assets.cmake: OUT, DIR
# and NAMES as there.
set(SOURCE "process/export/viewer/")
set(HEADER "process/export/viewer_page.h")
set(FUNCTION ViewerAssets)
include(${CMAKE_CURRENT_LIST_DIR}/embed_assets.cmake)
