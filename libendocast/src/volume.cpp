// Volume<T> is header-only; this unit anchors the library and instantiates the common types.
#include "endocast/volume.h"

namespace endocast {
template class Volume<uint8_t>;
template class Volume<int16_t>;
template class Volume<float>;
}  // namespace endocast
