from django.urls import path, re_path

from studyapp.survey import views

app_name = "survey"
urlpatterns = [
    path("s/<slug:slug>/", views.entry, name="entry"),
    path("s/<slug:slug>/<slug:name>/", views.page, name="page"),
    path("preview/<slug:slug>/", views.preview_entry, name="preview"),
    path("preview/<slug:slug>/<slug:name>/", views.preview_page, name="preview_page"),
    re_path(r"^c/(?P<token>[A-Za-z0-9_-]{8,64})\.(?P<ext>mp4|png|motion)$", views.clip, name="clip"),
    re_path(r"^p/(?P<token>[A-Za-z0-9_-]{8,64})\.(?P<ext>mp4|png|motion)$", views.preview_clip,
            name="preview_clip"),
]
