"""Top-level URLs: the admin and the participant pages."""

from django.contrib import admin
from django.urls import include, path

urlpatterns = [
    path("admin/", admin.site.urls),
    path("", include("studyapp.survey.urls")),
]

handler500 = "studyapp.survey.middleware.server_error"
