/* Placeholder: implemented in its own commit. */
#include "schnee/pb_sh.h"
