"""What a study gives back: the exported responses (``export``), analyses run from the
admin (``analysis_page``) and the plan page, the blindness audit over HTTP (``audit``),
the judged motions read back from the build (``study_motions``) and the reviewer's
bundle. Commands ``export_responses``, ``analyze``, ``plan``, ``correlate``, ``bundle``,
``audit_blindness``."""
