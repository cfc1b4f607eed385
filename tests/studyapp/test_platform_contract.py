"""Every registered crowd platform keeps the ``Platform`` contract: built from its example
settings with a code per outcome, it reads the ids of the entry links it makes, gives each
outcome its own code and nothing for a timed-out session, and sends only a participant
with a code on. A new platform is its module and its own tests; this holds it to the rest."""

from types import SimpleNamespace

import pytest
from django.http import QueryDict

from studyapp.crowd.platform import OUTCOMES, EntryRefused, list_platforms, make_platform
from studyapp.crowd.platform import registry

CODES = {outcome: f"C{index}CODE{index}" for index, outcome in enumerate(OUTCOMES)}


def build(name, **extra):
    cls = registry.get(name)
    return make_platform({"platform": name, "codes": CODES, **cls.example_settings, **extra})


def study():
    return SimpleNamespace(pk=7, slug="contract", completion_url="https://example.org/thanks")


@pytest.mark.parametrize("name", list_platforms())
def test_a_platform_reads_the_links_it_makes(name):
    platform = build(name)
    person = type(platform).example_person
    query = QueryDict(mutable=True)
    for key, value in platform.entry_params(study(), person):
        query[key] = value
    ids, key = platform.read_ids(query)
    if platform.id_params:
        assert key == f"{platform.id_params[0]}:{platform.normalise(platform.id_params[0], person)}"
        assert set(ids) <= set(platform.id_params + platform.extra_params)
    else:
        assert key == "" and ids == {}
    assert isinstance(platform.unique_ids(ids), dict)


@pytest.mark.parametrize("name", list_platforms())
def test_a_platform_refuses_a_link_without_the_id_it_requires(name):
    platform = build(name)
    if not (platform.require_id or platform.strict_ids):
        pytest.skip(f"{name} takes people without an id")
    with pytest.raises(EntryRefused):
        platform.read_ids(QueryDict())


@pytest.mark.parametrize("name", list_platforms())
def test_each_outcome_gets_its_own_code_and_only_a_coded_participant_is_sent_on(name):
    platform = build(name)
    platform.check_codes(list(OUTCOMES), checks=2)
    assert {outcome: platform.code_for(outcome) for outcome in OUTCOMES} == CODES
    assert platform.code_for("timed_out") == ""
    person = type(platform).example_person
    ids = {platform.id_params[0]: person} if platform.id_params else {}
    for code in ("", CODES["completed"]):
        participant = SimpleNamespace(study=study(), completion_code=code, external_ids=ids)
        url = platform.completion_url(participant)
        assert (url == "") == (code == ""), url
        assert not url or url.startswith(("https://", "http://"))
    assert platform.describe()["platform"] == name


@pytest.mark.parametrize("name", list_platforms())
def test_a_platform_refuses_a_setting_it_does_not_know(name):
    with pytest.raises(ValueError, match="unknown setting"):
        build(name, no_such_setting=1)
