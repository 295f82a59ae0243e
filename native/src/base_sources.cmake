# The bake core's sources that need neither an image library nor Embree itself (only pb_occluder.c
# calls Embree: embree_sources.cmake) (native/CMakeLists.txt).
set(PB_BASE_SOURCES
  src/pb_common.c
  src/pb_sh.c
  src/pb_shprobe.c
  src/pb_shprobe_read.c
  src/pb_shprobe_v3.c
  src/pb_shprobe_write.c
  src/pb_ambient_cube.c
  src/pb_interp.c
  src/pb_cotree.c
  src/pb_cotree_boxes.c
  src/pb_tetra.c
  src/pb_interp_v3.c
  src/pb_bricks.c
  src/pb_grid_field.c
  src/pb_refine.c
  src/pb_refine_axes.c
  src/pb_sky_sun.c
  src/pb_placement_ctx.c
  src/pb_octree.c
  src/pb_solid.c
  src/pb_classify.c
  src/pb_direct.c
)
