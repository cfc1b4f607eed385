"""Participant pages, the staff preview and clip serving; the pages live in ``flow`` (one
sequence for participants and previews) and ``preview`` (the store that keeps nothing)."""

from django.conf import settings
from django.contrib.admin.views.decorators import staff_member_required
from django.http import Http404
from django.shortcuts import get_object_or_404
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_safe

from studyapp.participation import fetch_log, flow, preview
from studyapp.stimuli import media
from studyapp.survey.models import Stimulus, Study, TrialItem

CONTENT_TYPES = {"mp4": "video/mp4", "png": "image/png", "motion": "application/octet-stream"}
FILES = media.STIMULUS_FILES


def kept_study(slug):
    """Return the study ``slug`` as this process keeps it (``flow.DatabaseStore.participant``
    checks its version before use), or raise Http404."""
    try:
        return Study.objects.cached(slug)
    except Study.DoesNotExist:
        raise Http404("no such study") from None


@never_cache
@require_safe
def entry(request, slug):
    try:
        response = flow.enter(request, kept_study(slug))
    except Study.DoesNotExist:  # deleted since this process read it
        raise Http404("no such study") from None
    return flow.keep_browser_state(request, response)


@never_cache
@require_http_methods(["GET", "POST"])
def page(request, slug, name):
    if name not in flow.PAGES:
        raise Http404("no such page")
    try:
        response = flow.show(request, kept_study(slug), name)
    except Study.DoesNotExist:
        raise Http404("no such study") from None
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
    if name not in flow.PAGES:
        raise Http404("no such page")
    study = get_object_or_404(Study, slug=slug)
    return flow.show(request, study, name, preview.PreviewStore(request))


def _serve(request, stimulus, ext, token, on_sent=None):
    """Serve the delivery ``token`` of a stimulus' ``ext`` file: bytes of its own, and an
    ETag of its own that changes with them (with the site's secret)."""
    name = getattr(stimulus, FILES[ext])
    seed = media.delivery_seed(token)
    etag = f'"{token}-{ext}-{seed[:4].hex()}"'
    try:
        # Only names under stimuli/ are opened, through default_storage (media.file_response).
        return media.file_response(request, name, CONTENT_TYPES[ext], etag, on_sent,
                                   delivery=(ext, seed))
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        raise Http404("no such clip") from None


@require_safe
def clip(request, token, ext):
    """Serve a trial item's video or poster under its own opaque token only.

    Every item (the same clip in a repeated trial too) has its own token, ETag and bytes
    (:mod:`rendering.delivery`), so nothing in the URL, the headers or a hash of the file
    tells two showings of a clip apart from two clips. Sending the last byte of a video (or of the in-browser player's payload) records the
    range sent (``TrialItem.fetched``, first as a witness no database lock holds up:
    :mod:`~studyapp.participation.fetch_log`): the server, not the page, knows whether a clip
    was fetched to its end.

    With ``STUDY_ACCEL_REDIRECT`` (production behind nginx, ``make serve``) the view only
    authorises the token and writes the delivery's file once; nginx sends the bytes
    (:func:`~studyapp.stimuli.media.accel_response`) and its access log of that internal
    location is read into the same witnesses (:mod:`~studyapp.participation.proxy_log`).
    """
    item = get_object_or_404(TrialItem.objects.select_related("stimulus"), token=token)
    location = getattr(settings, "STUDY_ACCEL_REDIRECT", "")
    if media.proxied(location):
        # The proxy sends the bytes; its access log is the record of what went out
        # (studyapp.participation.proxy_log folds it into the witnesses).
        try:
            return media.accel_response(request, getattr(item.stimulus, FILES[ext]),
                                        CONTENT_TYPES[ext], item.token, ext,
                                        media.delivery_seed(item.token), location)
        except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
            raise Http404("no such clip") from None
    on_sent = None
    if ext in ("mp4", "motion") and request.method == "GET":
        def on_sent(start, end, size, pk=item.pk, token=item.token):
            return fetch_log.note(pk, token, ext, start, end, size)
    return _serve(request, item.stimulus, ext, item.token, on_sent)


@staff_member_required
@require_safe
def preview_clip(request, token, ext):
    """Serve a stimulus' files to staff (previews, the admin) under the stimulus token."""
    stimulus = get_object_or_404(Stimulus, token=token)
    return _serve(request, stimulus, ext, f"s{stimulus.token}")
