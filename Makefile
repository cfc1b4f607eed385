# The two commands of the README: `make demo` and `make test`.
PY := .venv/bin/python
export PYOPENGL_PLATFORM ?= egl

.PHONY: setup demo test serve loadtest

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) manage.py demo

test: setup
	$(PY) -m pytest

# Production: gunicorn behind your HTTPS proxy (README, "Production").
serve: setup
	@bash scripts/serve.sh

# 500 concurrent bots against gunicorn + a fresh PostgreSQL database (docs/BENCHMARKS.md, "Load").
loadtest: setup
	$(PY) benchmarks/loadtest.py --participants 500 --trials 2 --time-limit 300
