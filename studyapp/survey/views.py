"""Participant pages, the staff preview and clip serving; the flows live in ``flow``
and ``preview``."""

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
    response = flow.enter(request, get_object_or_404(Study, slug=slug))
    return flow.keep_browser_state(request, response)


@never_cache
@require_http_methods(["GET", "POST"])
def page(request, slug, name):
    if name not in flow.PAGES:
        raise Http404("no such page")
    response = flow.show(request, get_object_or_404(Study, slug=slug), name)
    return flow.keep_browser_state(request, response)


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
    name = stimulus.video if ext == "mp4" else stimulus.poster
    tag = stimulus.video_hash or stimulus.token
    etag = f'"{tag}"' if ext == "mp4" else f'"{tag}-p"'
    try:
        # Only names under stimuli/ are opened, through default_storage (media.file_response).
        return media.file_response(request, name, CONTENT_TYPES[ext], etag)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        raise Http404("no such clip") from None
