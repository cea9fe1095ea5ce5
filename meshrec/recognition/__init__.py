"""Recognition over a library: every model registered, then ranked."""
