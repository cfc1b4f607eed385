"""Any other platform (CloudResearch Connect, SONA, a panel of your own): ``id_param``
names the query parameter that identifies a person, ``extra_params`` are recorded too,
``completion_url_template`` is where people go at the end, with ``{code}`` and ``{id}``
filled in."""

from __future__ import annotations

import re
from urllib.parse import quote

from studyapp.crowd.platform import Platform, registry


@registry.register("generic")
class Generic(Platform):
    label = "Crowd platform"
    own_settings = ("id_param", "extra_params", "completion_url_template")
    example_settings = {"id_param": "participantId", "extra_params": ["sessionId"],
                        "completion_url_template": "https://panel.example.org/done?c={code}&p={id}"}

    def __init__(self, settings):
        super().__init__(settings)
        param = settings.get("id_param")
        if not isinstance(param, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,49}", param):
            raise ValueError(f"crowd.id_param: {param!r} must name the query parameter that "
                             f"identifies a person, e.g. participantId")
        extra = settings.get("extra_params") or []
        if not isinstance(extra, list) or not all(isinstance(p, str) for p in extra):
            raise ValueError(f"crowd.extra_params: {extra!r} must be a list of parameter names")
        self.id_params = (param,)
        self.extra_params = tuple(extra)
        self.template = settings.get("completion_url_template") or ""
        self.redirects = bool(self.template)
        if self.template and not self.template.startswith(("https://", "http://")):
            raise ValueError(f"crowd.completion_url_template: {self.template!r} must be an "
                             f"http(s) URL with {{code}} (and {{id}}) in it")
        try:
            self.template.format(code="", id="")
        except (KeyError, IndexError, ValueError):
            raise ValueError("crowd.completion_url_template: only {code} and {id} may be "
                             "filled in") from None

    def completion_url(self, participant):
        if not participant.completion_code:
            return ""
        if not self.template:
            return participant.study.completion_url
        person = participant.external_ids.get(self.id_params[0], "")
        return self.template.format(code=quote(participant.completion_code),
                                    id=quote(person))
