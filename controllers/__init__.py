"""Semi-active control laws behind one interface (passive, skyhook, groundhook, clipped-optimal, ...)."""
