"""``Study.version``: one more on every UPDATE of a study row (a trigger, so queryset
updates, the admin and other nodes all count), for processes that keep the row.

SQLite drops a table's triggers when a migration remakes the table (as it does to alter
a column): a later migration that alters ``survey_study`` must create the trigger again
(``test_a_kept_study_row_is_read_again_once_any_update_changes_it`` fails otherwise)."""

from django.db import migrations, models

import studyapp.survey.models.study

POSTGRES = [
    """CREATE OR REPLACE FUNCTION survey_study_bump_version() RETURNS trigger AS $$
    BEGIN
        NEW.version := OLD.version + 1;
        RETURN NEW;
    END;
    $$ LANGUAGE plpgsql""",
    """CREATE TRIGGER survey_study_version BEFORE UPDATE ON survey_study
    FOR EACH ROW EXECUTE FUNCTION survey_study_bump_version()""",
]
POSTGRES_REVERSE = [
    "DROP TRIGGER IF EXISTS survey_study_version ON survey_study",
    "DROP FUNCTION IF EXISTS survey_study_bump_version()",
]
# SQLite: the trigger's own UPDATE sets version above OLD's, so its WHEN stops it firing
# again; a save from a row read before another update (its version older) moves it on too.
SQLITE = [
    """CREATE TRIGGER survey_study_version AFTER UPDATE ON survey_study
    FOR EACH ROW WHEN NEW.version <= OLD.version
    BEGIN
        UPDATE survey_study SET version = OLD.version + 1 WHERE id = NEW.id;
    END""",
]
SQLITE_REVERSE = ["DROP TRIGGER IF EXISTS survey_study_version"]


def create_trigger(apps, schema_editor):
    for statement in {"postgresql": POSTGRES, "sqlite": SQLITE}.get(schema_editor.connection.vendor, []):
        schema_editor.execute(statement)


def drop_trigger(apps, schema_editor):
    reverse = {"postgresql": POSTGRES_REVERSE, "sqlite": SQLITE_REVERSE}
    for statement in reverse.get(schema_editor.connection.vendor, []):
        schema_editor.execute(statement)


class Migration(migrations.Migration):

    dependencies = [
        ("survey", "0012_stop_rule"),
    ]

    operations = [
        migrations.AddField(
            model_name="study",
            name="version",
            field=models.BigIntegerField(default=studyapp.survey.models.study.new_version,
                                         editable=False),
        ),
        migrations.RunPython(create_trigger, drop_trigger),
    ]
