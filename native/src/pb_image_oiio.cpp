// Placeholder: OpenImageIO behind extern "C".
#include "schnee/pb_image.h"
