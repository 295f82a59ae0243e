# The bake core's one source that calls Embree, the occluder module (pb_occluder.h): compiled twice,
# linked as usual and through pb_embree_dyn.c's dlsym pointers (native/CMakeLists.txt). Its users
# (placement, solid test, classification, direct light) are in base_sources.cmake.
set(PB_EMBREE_SOURCES
  src/pb_occluder.c
)
