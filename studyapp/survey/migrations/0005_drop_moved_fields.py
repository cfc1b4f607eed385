"""Drop the fields 0004 moved, make item tokens unique, add the new constraints."""

import django.db.models.deletion
import studyapp.survey.models
from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ("survey", "0004_move_answers"),
    ]

    operations = [
        migrations.AlterField(
            model_name='trialitem',
            name='token',
            field=models.CharField(default=studyapp.survey.models.new_token, editable=False, max_length=32, unique=True),
        ),
        migrations.RemoveConstraint(
            model_name='stimulus',
            name='at_most_one_stimulus_role',
        ),
        migrations.RemoveConstraint(
            model_name='trialitem',
            name='one_item_per_stimulus',
        ),
        migrations.RemoveField(
            model_name='stimulus',
            name='is_catch',
        ),
        migrations.RemoveField(
            model_name='stimulus',
            name='is_reference',
        ),
        migrations.RemoveField(
            model_name='stimulus',
            name='is_standard_example',
        ),
        migrations.RemoveField(
            model_name='study',
            name='allow_ties',
        ),
        migrations.RemoveField(
            model_name='trial',
            name='choice',
        ),
        migrations.RemoveField(
            model_name='trial',
            name='reference',
        ),
        migrations.RemoveField(
            model_name='trialitem',
            name='judged_real',
        ),
        migrations.RemoveField(
            model_name='trialitem',
            name='rank',
        ),
        migrations.RemoveField(
            model_name='trialitem',
            name='rating',
        ),
        migrations.AddConstraint(
            model_name='trialitem',
            constraint=models.UniqueConstraint(condition=models.Q(('role', 'judged')), fields=('trial', 'stimulus'), name='one_judged_item_per_stimulus'),
        ),
    ]
