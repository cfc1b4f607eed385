"""Study.player holds the figure a style declares (its player_figure): no choices, so a new style needs no migration."""

from django.db import migrations, models


class Migration(migrations.Migration):

    dependencies = [
        ('survey', '0008_stimulus_checkpoint'),
    ]

    operations = [
        migrations.AlterField(
            model_name='study',
            name='player',
            field=models.CharField(blank=True, help_text="The figure the in-page player (WebGL) draws where the browser can, the mp4 otherwise (the style's player_figure, e.g. stick or body); blank: the mp4 only. Needs clips built with render.player: webgl.", max_length=8),
        ),
    ]
