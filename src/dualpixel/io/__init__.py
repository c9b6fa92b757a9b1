"""File input and output at the edges of the library: atomic writes, images, depth maps."""
