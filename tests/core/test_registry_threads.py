"""The lazy registry from several threads at once (the console's workers and screens): a plugin imported
by one thread while another collects is listed once, never reported as its own duplicate."""

from __future__ import annotations

import threading

from mirrorlab.core.registry import Registry

#: algorithms of different built-in plugins (each import is lazy)
NAMES = ("angular_momentum", "detect_markers", "retarget", "four_bar", "track", "lab_survey", "derivatives",
         "calibrate_pinhole")


def ask_at_once(registry: Registry, names: tuple[str, ...]) -> list[BaseException]:
    """Each name asked from a thread of its own, all released together; what they raised."""
    start = threading.Barrier(len(names))
    errors: list[BaseException] = []

    def ask(name: str) -> None:
        start.wait()
        try:
            assert registry.algorithm(name).name == name
        except BaseException as exc:  # reported by the test thread
            errors.append(exc)

    threads = [threading.Thread(target=ask, args=(name,)) for name in names]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return errors


def test_names_asked_from_many_threads_have_one_provider_each() -> None:
    for _ in range(5):
        registry = Registry(entry_points=False)
        errors = ask_at_once(registry, NAMES * 2)
        assert errors == [], errors[0]
        assert all(len(registry.providers("algorithm", name)) == 1 for name in NAMES)
