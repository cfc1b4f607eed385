# The two commands of the README: `make demo` and `make test`.
PY := .venv/bin/python
export PYOPENGL_PLATFORM ?= egl
# Where `make demo` serves: make demo PORT=8010, or ADDR=0.0.0.0:8010 (all interfaces).
PORT ?= 8000
ADDR ?= 127.0.0.1:$(PORT)

.PHONY: setup demo test serve loadtest

setup:
	@bash scripts/setup.sh

# ARGS: more options of `manage.py demo`, e.g. ARGS=--no-serve (build only, as CI does).
demo: setup
	$(PY) manage.py demo --addr $(ADDR) $(ARGS)

test: setup
	$(PY) -m pytest

# Production: gunicorn behind your HTTPS proxy (README, "Production").
serve: setup
	@bash scripts/serve.sh

# 500 concurrent bots against gunicorn + a fresh PostgreSQL database (docs/BENCHMARKS.md, "Load");
# add ARGS="--think 10" for participants who take about 10 s per trial, ARGS="--arrivals 2000
# --over 300 --think 10" for a launch (participants arriving over 5 minutes), "--study webgl"
# for clips played in the page.
loadtest: setup
	$(PY) benchmarks/loadtest.py --participants 500 --trials 6 --time-limit 600 $(ARGS)
