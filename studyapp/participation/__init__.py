"""Taking part: the page sequence (consent, instructions, trials, demographics, done), trial
forms and answers, balanced assignment, the staff preview, durations, entry rate limits
and the page-driven bots (``simulate_participants``)."""
