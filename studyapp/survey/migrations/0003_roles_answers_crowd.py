"""Add stimulus roles, per-item tokens (filled in 0004), answers per criterion, crowd fields."""

import django.db.models.deletion
import studyapp.survey.models
from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('survey', '0002_build_job'),
    ]

    operations = [
        migrations.AddField(
            model_name='participant',
            name='outcome',
            field=models.CharField(blank=True, choices=[('completed', 'Completed'), ('failed_attention', 'Failed the attention checks'), ('no_consent', 'Did not consent'), ('screened_out', 'Screened out'), ('timed_out', 'Ran out of time')], help_text='Blank while taking part.', max_length=20),
        ),
        migrations.AddField(
            model_name='stimulus',
            name='motion',
            field=models.CharField(blank=True, help_text="Storage name of the in-browser player's data.", max_length=300),
        ),
        migrations.AddField(
            model_name='stimulus',
            name='prompt',
            field=models.TextField(blank=True, help_text='The text prompt the motion answers, if any.'),
        ),
        migrations.AddField(
            model_name='stimulus',
            name='role',
            field=models.CharField(choices=[('judged', 'Judged'), ('catch', 'Catch (an obviously broken clip)'), ('reference', 'Reference (a real clip shown or hidden for comparison)'), ('example', 'Scoring-standard example'), ('anchor', 'Low anchor (a degraded clip rated among the others)'), ('practice', 'Practice only')], default='judged', max_length=16),
        ),
        migrations.AddField(
            model_name='study',
            name='criteria',
            field=models.JSONField(blank=True, default=list, help_text='Questions asked of the same clips, e.g. [{"key": "naturalness", "question": "..."}, {"key": "fit", "question": "..."}]; empty: the type\'s one question.'),
        ),
        migrations.AddField(
            model_name='study',
            name='crowd',
            field=models.JSONField(blank=True, default=dict, help_text='Crowd platform: {"platform": "prolific", "codes": {"completed": ..., "failed_attention": ..., "no_consent": ..., "screened_out": ...}, "time_limit_minutes": 30}; see README, "Crowd platforms".'),
        ),
        migrations.AddField(
            model_name='study',
            name='max_failed_catch',
            field=models.PositiveSmallIntegerField(default=0, help_text='More failed catch trials than this: the outcome is a failed attention check (its own completion code).'),
        ),
        migrations.AddField(
            model_name='study',
            name='options',
            field=models.JSONField(blank=True, default=dict, help_text="The study type's own options (see README)."),
        ),
        migrations.AddField(
            model_name='trial',
            name='answers',
            field=models.JSONField(blank=True, default=dict, help_text='Answers on the trial itself, per criterion.'),
        ),
        migrations.AddField(
            model_name='trial',
            name='events',
            field=models.JSONField(blank=True, default=list, help_text='What the page reported: [ms since shown, event, item position] each.'),
        ),
        migrations.AddField(
            model_name='trial',
            name='prompt',
            field=models.TextField(blank=True, help_text='The text prompt shown, if any.'),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='answers',
            field=models.JSONField(blank=True, default=dict, help_text='Answers per criterion.'),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='fetched',
            field=models.JSONField(blank=True, default=list, help_text='Byte ranges of the clip sent whole.'),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='fetched_at',
            field=models.DateTimeField(blank=True, help_text='When the whole clip had been sent.', null=True),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='required',
            field=models.BooleanField(default=True, help_text="Must be fetched whole before the trial's answer is taken."),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='role',
            field=models.CharField(choices=[('judged', 'Judged'), ('reference', 'Reference shown beside the judged clips'), ('example', 'Scoring-standard example')], default='judged', max_length=16),
        ),
        migrations.AlterField(
            model_name='participant',
            name='completion_code',
            field=models.CharField(blank=True, max_length=64),
        ),
        migrations.AlterField(
            model_name='scoringstandard',
            name='stimulus',
            field=models.ForeignKey(help_text='The example clip: a stimulus whose role is example, never rated.', limit_choices_to={'role': 'example'}, on_delete=django.db.models.deletion.RESTRICT, related_name='standards', to='survey.stimulus'),
        ),
        migrations.AlterField(
            model_name='stimulus',
            name='token',
            field=models.CharField(default=studyapp.survey.models.new_token, editable=False, help_text='For staff previews only; participants see per-trial tokens.', max_length=32, unique=True),
        ),
        migrations.AlterField(
            model_name='stimulus',
            name='video',
            field=models.CharField(help_text='Storage name of the mp4.', max_length=300),
        ),
        migrations.AlterField(
            model_name='study',
            name='completion_url',
            field=models.URLField(blank=True, help_text='Where to send participants at the end (studies without a platform).'),
        ),
        migrations.AlterField(
            model_name='study',
            name='max_participants',
            field=models.PositiveIntegerField(blank=True, help_text='Finished and active participants at most.', null=True),
        ),
        migrations.AlterField(
            model_name='trial',
            name='shown_at',
            field=models.DateTimeField(blank=True, help_text='When the page was served.', null=True),
        ),
        migrations.AlterField(
            model_name='trialitem',
            name='plays',
            field=models.PositiveIntegerField(default=0, help_text='Complete plays the page reported.'),
        ),
        migrations.AlterField(
            model_name='trialitem',
            name='position',
            field=models.PositiveSmallIntegerField(help_text='Place on screen, 0 = first; shown-only clips come after the judged ones.'),
        ),
        migrations.AddField(
            model_name='trialitem',
            name='token',
            field=models.CharField(editable=False, max_length=32, null=True),
        ),
    ]
