"""Evaluation against truth: trajectory errors, parameter errors, consistency."""
