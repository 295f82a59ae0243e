# The bake core's sources that call Embree (pb_occluder.c, the only one) and those built on it:
# compiled twice, linked as usual and through pb_embree_dyn.c (native/CMakeLists.txt).
set(PB_EMBREE_SOURCES
  src/pb_occluder.c
  src/pb_placement_ctx.c
  src/pb_octree.c
  src/pb_solid.c
  src/pb_classify.c
  src/pb_direct.c
)
