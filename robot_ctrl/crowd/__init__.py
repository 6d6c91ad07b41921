"""Coupled gaits of several humanoids: coupling graphs, contraction certificates, crowd simulation."""
