from django.apps import AppConfig


class SurveyConfig(AppConfig):
    name = "studyapp.survey"
    label = "survey"
    verbose_name = "Perceptual studies"
