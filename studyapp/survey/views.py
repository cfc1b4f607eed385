"""Participant pages, the staff preview and clip serving; the flows live in ``flow``
and ``preview``."""

from pathlib import Path

from django.conf import settings
from django.contrib.admin.views.decorators import staff_member_required
from django.http import Http404
from django.shortcuts import get_object_or_404
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_safe

from studyapp.survey import flow, media, preview
from studyapp.survey.models import Stimulus, Study

CONTENT_TYPES = {"mp4": "video/mp4", "png": "image/png"}


@never_cache
@require_safe
def entry(request, slug):
    return flow.enter(request, get_object_or_404(Study, slug=slug))


@never_cache
@require_http_methods(["GET", "POST"])
def page(request, slug, name):
    if name not in flow.PAGES:
        raise Http404("no such page")
    return flow.show(request, get_object_or_404(Study, slug=slug), name)


@staff_member_required
@never_cache
@require_safe
def preview_entry(request, slug):
    return preview.start(request, get_object_or_404(Study, slug=slug))


@staff_member_required
@never_cache
@require_http_methods(["GET", "POST"])
def preview_page(request, slug, name):
    if name not in preview.PAGES:
        raise Http404("no such page")
    return preview.show(request, get_object_or_404(Study, slug=slug), name)


@require_safe
def clip(request, token, ext):
    """Serve a stimulus video or poster under its opaque token only."""
    stimulus = get_object_or_404(Stimulus, token=token)
    relative = stimulus.video if ext == "mp4" else stimulus.poster
    root = Path(settings.MEDIA_ROOT).resolve()
    path = (root / relative).resolve() if relative else None
    if path is None or not path.is_relative_to(root) or not path.is_file():
        raise Http404("no such clip")
    tag = stimulus.video_hash or stimulus.token
    etag = f'"{tag}"' if ext == "mp4" else f'"{tag}-p"'
    return media.file_response(request, path, CONTENT_TYPES[ext], etag)
