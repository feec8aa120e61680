"""The operator page of ``rigd serve`` (``GET /``, ``/ui/live``, ``/static``): its routes, Jinja2 templates,
script and style sheet. It reads through ``rigd.api``'s read functions and models; ``rigd.api.main`` mounts it
with :func:`install`, and nothing else in ``rigd.api`` imports it."""

from rigd.web.routes import install

__all__ = ["install"]
