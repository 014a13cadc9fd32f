"""Experiments: collect every wrap of a dataset, reproduce the paper end to end, write
the report."""
