"""Frame images: where a frame's pixels are and how they are served."""
