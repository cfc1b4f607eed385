"""Top-level URLs: the admin, the participant pages and arenas' leaderboards."""

from django.contrib import admin
from django.urls import include, path

from studyapp.results import leaderboard

urlpatterns = [
    path("admin/", admin.site.urls),
    # An arena's public leaderboard (read-only, no login).
    path("arena/<slug:slug>/", leaderboard.page, name="arena"),
    path("arena/<slug:slug>.json", leaderboard.data, name="arena_json"),
    path("", include("studyapp.survey.urls")),
]

handler500 = "studyapp.survey.middleware.server_error"
