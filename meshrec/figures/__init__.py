"""Pictures: the open3d viewer and the matplotlib figures, drawn from results."""
