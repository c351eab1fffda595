# Quick start: `make demo` (set-up, then render the seed scene) and `make test` (set-up, then all tests).
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.setup-done
OUT    := out

.PHONY: setup demo test test-fast slow-list validate benchmark clean

setup: $(STAMP)

$(STAMP): pyproject.toml setup.py raytracer/_native/bvh.cc raytracer/_native/kinds.h raytracer/_native/antialias.cc scripts/setup.sh
	bash scripts/setup.sh
	touch $(STAMP)

demo: setup
	@mkdir -p $(OUT)
	$(VENV)/bin/raytracer render examples/scenes/seed.pov -o $(OUT)/seed.png -W 640 -H 480
	$(VENV)/bin/raytracer render examples/scenes/seed.pov -o $(OUT)/seed.exr -W 640 -H 480

# The full suite, slow tests included (this is what CI runs). worksteal: an idle worker takes tests
# from a busy one, so no file's long tests pin the run to one core; tests/conftest.py gives the run
# one JAX compilation cache that the workers share. Three workers on two cores: tests wait on
# POV-Ray, Mitsuba and their own subprocesses. 10.5 min on 2 cores at 036bbe1 (docs/test-suite.md).
test: setup
	$(PY) -m pytest -q -n 3 --dist worksteal -p no:cacheprovider

# Everything but the tests marked slow: in their files, or listed in tests/slow_tests.txt (those that
# took 0.5 s or more in a full run; `make slow-list` measures them again). 48 s on 2 cores (978 tests).
test-fast: setup
	$(PY) -m pytest -q -n 2 --dist worksteal -m "not slow" -p no:cacheprovider

# The full suite with a JUnit report, then tests/slow_tests.txt written from its times.
slow-list: setup
	@mkdir -p $(OUT)
	$(PY) -m pytest -q -n 2 --dist worksteal -p no:cacheprovider --junitxml=$(OUT)/junit.xml
	$(PY) scripts/slow_tests.py $(OUT)/junit.xml

validate: setup
	$(PY) -m validation --report $(OUT)/validation

clean:
	rm -rf $(OUT) .pytest_cache
