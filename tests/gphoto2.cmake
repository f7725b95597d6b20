# The gphoto2 camera backend against libgphoto2's own virtual camera. A fixture builds the
# virtual camera (scripts/build-vusb-camera.sh, cached outside the repository); the test
# binary runs through scripts/with-vusb-camera.sh, which points libgphoto2 at it.
if(RIG_WITH_GPHOTO2)
  add_executable(gphoto2_camera_test ${CMAKE_CURRENT_SOURCE_DIR}/gphoto2/gphoto2_camera_test.cc
                                     ${CMAKE_CURRENT_SOURCE_DIR}/test_env.cc)
  target_link_libraries(gphoto2_camera_test PRIVATE rig_test_support rig_commands rig_sim
                        rig_process rig_capture rig_config GTest::gtest GTest::gmock GTest::gtest_main)
  target_include_directories(gphoto2_camera_test PRIVATE ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR})
  target_compile_definitions(gphoto2_camera_test PRIVATE ${RIG_TEST_DEFINITIONS})
  rig_warnings(gphoto2_camera_test)
  add_dependencies(gphoto2_camera_test rig)
  add_test(NAME gphoto2.build_virtual_camera
           COMMAND ${PROJECT_SOURCE_DIR}/scripts/build-vusb-camera.sh)
  set_tests_properties(gphoto2.build_virtual_camera PROPERTIES FIXTURES_SETUP vusb TIMEOUT 900
                       LABELS capture)
  add_test(NAME gphoto2.virtual_camera
           COMMAND ${PROJECT_SOURCE_DIR}/scripts/with-vusb-camera.sh $<TARGET_FILE:gphoto2_camera_test>)
  set_tests_properties(gphoto2.virtual_camera PROPERTIES FIXTURES_REQUIRED vusb TIMEOUT 300
                       LABELS capture)
endif()
