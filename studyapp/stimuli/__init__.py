"""The offline build of a study's clips: configs (``config``, ``source_config``), sources and
training (``sources``), the build (``build``), catch clips, rendering fanned out to Celery
workers (``render_fanout``), registration (``clips``) and blind delivery (``media``).
Commands ``build_stimuli`` and ``demo``; nothing here needs a request."""
