from django.apps import AppConfig


class SurveyConfig(AppConfig):
    name = "studyapp.survey"
    label = "survey"
    verbose_name = "Perceptual studies"

    def ready(self):
        from django.contrib.auth.signals import user_login_failed

        from studyapp.survey.ratelimit import count_failed_login

        user_login_failed.connect(count_failed_login, dispatch_uid="survey-login-limit")
