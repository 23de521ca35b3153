from mimicbench.datagen.stage_runner import run_stage, summarize_statuses


def flaky(x):
    if x % 3 == 0:
        raise ValueError(f"bad item {x}")
    return x * 10


def test_failures_become_status_rows_and_others_go_on():
    for jobs in (1, 2):
        results, statuses = run_stage(list(range(7)), flaky, "unit", name_of=lambda x: f"item{x}", jobs=jobs, progress=False)
        assert results == [10, 20, 40, 50]
        failed = [s for s in statuses if s.status == "failed"]
        assert [s.asset for s in failed] == ["item0", "item3", "item6"]
        assert all("ValueError: bad item" in s.reason for s in failed)
        assert "4 ok, 3 failed" in summarize_statuses(statuses)


def test_on_done_sees_every_item_once_as_it_finishes():
    for jobs in (1, 2):
        seen = []
        run_stage(list(range(7)), flaky, "unit", jobs=jobs, progress=False,
                  on_done=lambda i, ok, result: seen.append((i, ok, result)))
        assert sorted(seen) == [(i, i % 3 != 0, None if i % 3 == 0 else i * 10) for i in range(7)]
