// TriangleMesh is a plain struct; this unit anchors the library.
#include "meshpost/mesh.h"
