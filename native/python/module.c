/* Placeholder: the CPython extension module _schnee_native (stable ABI 3.11). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef schnee_module = {PyModuleDef_HEAD_INIT, "_schnee_native", NULL, -1, NULL,
                                           NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__schnee_native(void) { return PyModule_Create(&schnee_module); }
