"""Streams, file formats, sources and time association."""
