/* The window's input (keyboard and mouse through GLFW), out of the frame loop of sv_window.c:
 *   Esc closes; P toggles probe colours, C the probe view, B cycles the brick view (cells, texels,
 *   validity), N selects the next object, M cycles the probe mode (on key press edges); right mouse drag looks, W/A/S/D moves, Q/E down/up (Shift x4);
 *   J/L, I/K, U/O move the selected object along x, z, y (its probe is re-queried).
 * sv_input_init once from the start view, then sv_input_update once per frame, which edits the view
 * and the scene. No Vulkan. */
#ifndef SV_INPUT_H
#define SV_INPUT_H

#include "sv_probes.h"
#include "sv_renderer.h"
#include "sv_scene.h"

struct GLFWwindow;

/* Free-flying camera: position, yaw (about +Y, 0 = looking along -Z), pitch. */
typedef struct sv_fly_camera {
    float pos[3];
    float yaw, pitch;
} sv_fly_camera;

typedef struct sv_input {
    struct GLFWwindow *win;
    sv_fly_camera cam;
    float speed;       /* metres per second: a quarter of the scene's larger horizontal side, at least 0.5 */
    uint32_t selected; /* the object N selected and J..O move */
    double mouse_x, mouse_y;
    bool dragging;                               /* the right button was down last frame */
    bool prev_p, prev_c, prev_n, prev_m, prev_b; /* key states last frame (toggles act on press edges) */
} sv_input;

/* The camera from `view` (its position and forward direction), the speed from the scene's bounds. */
void sv_input_init(sv_input *in, struct GLFWwindow *win, const sv_view *view, const sv_scene *scene);
/* One frame's input, `dt` seconds after the last: edits `view` (camera, modes) and moves the
 * selected object in `scene` (re-assigning its probes). */
void sv_input_update(sv_input *in, float dt, sv_view *view, sv_scene *scene, sv_probes *probes);

#endif
