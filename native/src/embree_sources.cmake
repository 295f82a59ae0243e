# The bake core's sources that call Embree: compiled twice, linked as usual and through pb_embree_dyn.c
# (native/CMakeLists.txt).
set(PB_EMBREE_SOURCES
  src/pb_octree.c
  src/pb_direct.c
  src/pb_occluder.c
)
