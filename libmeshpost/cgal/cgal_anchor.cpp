// Anchor of the GPL target meshpost_cgal; CGAL-based algorithms live beside this file.
#include "meshpost/mesh.h"
