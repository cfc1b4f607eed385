"""Generative methods of motion and sampling from them (or from real data) alike.

This package never imports Django. It builds on :mod:`motion` (the data model, datasets
and files) and keeps every tensor inside: :mod:`generation.methods` is the registry of
methods (``train``, ``sample``, ``save``, ``load``), :mod:`generation.sampling` draws
motion sets from a method or a dataset the same way.
"""
