"""Variables, keys and the graph builder."""
