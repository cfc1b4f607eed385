"""Crowd platforms: the ``Platform`` interface (``platform``: entry, exit, codes per outcome,
an optional API client), one module per platform (``platforms/``) and Prolific's API
(``prolific/``, command ``prolific``)."""
