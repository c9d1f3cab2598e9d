# qd_box2d_profiling_off: link it into every executable or plugin that runs Box2D episodes
# (box2d_profiling_off.cpp says why). An INTERFACE library, so each consumer compiles the file into
# itself: an unreferenced object in a static library would never be linked.
if(NOT TARGET qd_box2d_profiling_off)
  add_library(qd_box2d_profiling_off INTERFACE)
  target_sources(qd_box2d_profiling_off INTERFACE ${CMAKE_CURRENT_LIST_DIR}/box2d_profiling_off.cpp)
  target_link_libraries(qd_box2d_profiling_off INTERFACE box2d::box2d)
endif()

# A test that the plugin exports the replacement (hidden symbols would leave libbox2d's in use).
function(qd_test_box2d_profiling_off plugin)
  if(BUILD_TESTING)
    add_test(NAME ${plugin}.box2d_profiling_off
             COMMAND sh -c "nm -D --defined-only \"$1\" | grep -q ' T _ZN7b2Timer5ResetEv$'" sh $<TARGET_FILE:${plugin}>)
  endif()
endfunction()
