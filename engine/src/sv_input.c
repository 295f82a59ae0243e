/* The window's input: keyboard toggles, the free-flying camera, moving the selected object (see
 * sv_input.h). */
#include "sv_input.h"

#include <math.h>
#include <string.h>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include "sv_gpu_brick_view.h"
#include "sv_math.h"

static void fly_forward(const sv_fly_camera *c, float f[3])
{
    f[0] = sinf(c->yaw) * cosf(c->pitch);
    f[1] = sinf(c->pitch);
    f[2] = -cosf(c->yaw) * cosf(c->pitch);
}

static void fly_to_view(const sv_fly_camera *c, sv_view *v)
{
    float f[3], target[3], up[3] = {0, 1, 0};
    fly_forward(c, f);
    for (int k = 0; k < 3; ++k) target[k] = c->pos[k] + f[k];
    sv_mat4_look_at(c->pos, target, up, v->view);
    memcpy(v->camera_pos, c->pos, sizeof(c->pos));
}

void sv_input_init(sv_input *in, GLFWwindow *win, const sv_view *view, const sv_scene *scene)
{
    memset(in, 0, sizeof(*in));
    in->win = win;
    memcpy(in->cam.pos, view->camera_pos, sizeof(in->cam.pos));
    /* view rows: row 2 = -forward */
    float fwd[3] = {-view->view[2], -view->view[6], -view->view[10]};
    in->cam.pitch = asinf(fmaxf(-1.0f, fminf(1.0f, fwd[1])));
    in->cam.yaw = atan2f(fwd[0], -fwd[2]);
    in->speed = 1.0f;
    if (scene->aabb_min[0] <= scene->aabb_max[0])
        in->speed = fmaxf(
            0.5f, 0.25f * fmaxf(scene->aabb_max[0] - scene->aabb_min[0], scene->aabb_max[2] - scene->aabb_min[2]));
}

/* Toggles on key press edges. */
static void update_toggles(sv_input *in, sv_view *view, const sv_scene *scene)
{
    GLFWwindow *win = in->win;
    if (glfwGetKey(win, GLFW_KEY_ESCAPE) == GLFW_PRESS) glfwSetWindowShouldClose(win, 1);
    bool p = glfwGetKey(win, GLFW_KEY_P) == GLFW_PRESS, c = glfwGetKey(win, GLFW_KEY_C) == GLFW_PRESS;
    bool n = glfwGetKey(win, GLFW_KEY_N) == GLFW_PRESS, m = glfwGetKey(win, GLFW_KEY_M) == GLFW_PRESS;
    /* M cycles the probe mode: per material -> object -> pixel -> (any later mode) -> off -> per
     * material, through the values of sv_gpu.h (MATERIAL is the last, OFF the first). */
    if (m && !in->prev_m)
        view->probe_mode = view->probe_mode == SV_PROBE_MODE_MATERIAL        ? SV_PROBE_MODE_OFF + 1u
                           : view->probe_mode == SV_PROBE_MODE_OFF           ? SV_PROBE_MODE_MATERIAL
                           : view->probe_mode + 1u == SV_PROBE_MODE_MATERIAL ? SV_PROBE_MODE_OFF
                                                                             : view->probe_mode + 1u;
    in->prev_m = m;
    if (p && !in->prev_p)
        view->debug_mode = view->debug_mode == SV_DEBUG_PROBE_COLOR ? SV_DEBUG_NONE : SV_DEBUG_PROBE_COLOR;
    if (c && !in->prev_c) view->show_cells = !view->show_cells;
    /* B: the brick view's next mode (sv_brick_view.h; shown with --probe-path bricks), the probe view on. */
    bool b = glfwGetKey(win, GLFW_KEY_B) == GLFW_PRESS;
    if (b && !in->prev_b) {
        view->brick_view = view->show_cells ? (view->brick_view + 1u) % SV_BRICK_VIEW_COUNT : view->brick_view;
        view->show_cells = true;
    }
    in->prev_b = b;
    if (n && !in->prev_n && scene->object_count) in->selected = (in->selected + 1) % scene->object_count;
    in->prev_p = p;
    in->prev_c = c;
    in->prev_n = n;
}

/* Free-fly camera: right mouse drag looks, WASD/QE moves `step` metres. */
static void update_camera(sv_input *in, float step, sv_view *view)
{
    GLFWwindow *win = in->win;
    sv_fly_camera *cam = &in->cam;
    double mx, my;
    glfwGetCursorPos(win, &mx, &my);
    bool rmb = glfwGetMouseButton(win, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
    bool moved = false;
    if (rmb && in->dragging) {
        cam->yaw += (float)(mx - in->mouse_x) * 0.004f;
        cam->pitch = fmaxf(-1.55f, fminf(1.55f, cam->pitch - (float)(my - in->mouse_y) * 0.004f));
        moved = mx != in->mouse_x || my != in->mouse_y;
    }
    in->dragging = rmb;
    in->mouse_x = mx;
    in->mouse_y = my;
    float f[3], right[3];
    fly_forward(cam, f);
    right[0] = cosf(cam->yaw);
    right[1] = 0.0f;
    right[2] = sinf(cam->yaw);
    struct {
        int key;
        const float *dir;
        float sign;
    } keys[] = {
        {GLFW_KEY_W, f, 1},
        {GLFW_KEY_S, f, -1},
        {GLFW_KEY_D, right, 1},
        {GLFW_KEY_A, right, -1},
    };
    for (size_t k = 0; k < sizeof(keys) / sizeof(keys[0]); ++k)
        if (glfwGetKey(win, keys[k].key) == GLFW_PRESS) {
            for (int j = 0; j < 3; ++j) cam->pos[j] += keys[k].sign * step * keys[k].dir[j];
            moved = true;
        }
    if (glfwGetKey(win, GLFW_KEY_E) == GLFW_PRESS) cam->pos[1] += step, moved = true;
    if (glfwGetKey(win, GLFW_KEY_Q) == GLFW_PRESS) cam->pos[1] -= step, moved = true;
    if (moved) fly_to_view(cam, view);
}

/* Moves the selected object `step` metres; its probe is re-queried by sv_probes_assign. */
static void update_object(sv_input *in, float step, sv_scene *scene, sv_probes *probes)
{
    if (!scene->object_count) return;
    int move_keys[6] = {GLFW_KEY_J, GLFW_KEY_L, GLFW_KEY_K, GLFW_KEY_I, GLFW_KEY_U, GLFW_KEY_O};
    float delta[3] = {0, 0, 0};
    for (int k = 0; k < 6; ++k)
        if (glfwGetKey(in->win, move_keys[k]) == GLFW_PRESS)
            delta[k / 2 == 0 ? 0 : k / 2 == 1 ? 2 : 1] += (k % 2 ? 1.0f : -1.0f) * step;
    if (delta[0] != 0 || delta[1] != 0 || delta[2] != 0) {
        uint32_t node = scene->objects[in->selected].node;
        float t[3];
        const float *local = scene->node_local + 16 * node;
        for (int k = 0; k < 3; ++k) t[k] = local[12 + k] + delta[k];
        sv_scene_set_translation(scene, node, t);
    }
    sv_probes_assign(probes, scene);
}

void sv_input_update(sv_input *in, float dt, sv_view *view, sv_scene *scene, sv_probes *probes)
{
    update_toggles(in, view, scene);
    float step = in->speed * dt * (glfwGetKey(in->win, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 4.0f : 1.0f);
    update_camera(in, step, view);
    update_object(in, step, scene, probes);
}
