# The viewer schnee-view (and schnee-view-noimage) (engine/CMakeLists.txt).
set(SV_VIEW_SOURCES
  src/main.c
  src/sv_app.c
  src/sv_vk.c
  src/sv_scene.c
  src/sv_renderer.c
  src/sv_upload.c
  src/sv_bricks.c
  src/sv_bricks_vis.c
  src/sv_brick_view.c
  src/sv_shadows.c
  src/sv_shadow_math.c
  src/sv_pipelines.c
  src/sv_input.c
  src/sv_headless.c
  src/sv_window.c
)
