"""Guided clicking of a collection's template curves in a real browser (Debian's Chromium through Playwright)
against a real ``python -m curvefm.service`` process: a collection with two template curves on a small ellipsoid and
one member (a stretched copy, same vertex ids), made through the API; in the page the member is opened, its first
template curve answered by real clicks on the target, another skipped, and the collection run as a batch whose
archive is downloaded. Screenshots go to ``test-artifacts/ui/``."""

from __future__ import annotations

import numpy as np
import pytest
from support.paths import REPO
from support.processes import add_user
from support.shapes import ellipsoid, off_bytes
from support.ui import (
    VIEWPORT,
    canvas_pixels,
    changed_fraction,
    endpoint_pairs,
    next_frames,
    open_session,
    pickable_vertices,
    sample_count,
)

ARTIFACTS = REPO / "test-artifacts" / "ui"
K = 20
TEMPLATE_CURVES = [{"name": "spine", "waypoints": [10, 500]}, {"name": "tail", "waypoints": [30, 900]}]


@pytest.fixture(scope="module")
def served(module_processes, tmp_path_factory):
    """A server (jobs in-process) with a collection c of two template curves and one member m1 whose bases are ready."""
    api = module_processes.api(tmp_path_factory.mktemp("ui-collections") / "data")
    shapes = []
    for radii in ((1.0, 0.7, 0.5), (1.1, 0.6, 0.55)):
        upload = api.client.post("/shapes", files={"file": ("ellipsoid.off", off_bytes(ellipsoid(radii=radii)))})
        shapes.append(upload.raise_for_status().json()["id"])
        job = api.client.post(f"/shapes/{shapes[-1]}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    body = {"name": "ellipsoids", "template": shapes[0], "curves": TEMPLATE_CURVES, "members": [shapes[1]], "k": K}
    view = api.client.post("/collections", json=body).raise_for_status().json()
    assert [m["basis"] for m in view["members"]] == ["ready"]
    return api, view


def member_status(api, collection_id: str) -> dict:
    (member,) = api.client.get(f"/collections/{collection_id}").raise_for_status().json()["members"]
    return member


def current(page):
    return page.evaluate("window.curvefm.guide && window.curvefm.guide.current")


def wait_for_current(page, curve_id) -> None:
    page.wait_for_function(
        "(id) => window.curvefm.ready && window.curvefm.guide && window.curvefm.guide.current === id", arg=curve_id
    )


def test_a_member_is_clicked_curve_by_curve_skipped_and_run(browser, served):
    api, view = served
    collection_id, (member,) = view["collection"]["id"], view["members"]
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, api.url, member["session"], token=api.token)

    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    page.click('#member-list li[data-member-id="m1"] button[data-action="open"]')
    wait_for_current(page, "t1")
    assert page.text_content("#guide-prompt").startswith("t1 'spine': click its start on the member")
    assert page.text_content("#hint") == page.text_content("#guide-prompt")
    assert "0/2 curves" in page.text_content('#member-list li[data-member-id="m1"]')
    page.click("#guide-skip")
    wait_for_current(page, "t2")
    assert page.get_attribute("#template-curves li.current", "data-template-curve") == "t2"
    page.click("#guide-previous")
    wait_for_current(page, "t1")

    page.uncheck("#show-curves")  # compare the carried texture alone
    before = canvas_pixels(page, "target")
    ((start, end),) = endpoint_pairs(pickable_vertices(page), 1, seed=2)
    samples = sample_count(page)
    page.mouse.click(*start["target"])
    next_frames(page)
    assert page.text_content("#guide-prompt").startswith("t1 'spine': click its end on the member")
    page.mouse.click(*end["target"])
    page.wait_for_function("(n) => window.curvefmStats.samples.length > n", arg=samples, timeout=30_000)
    assert page.evaluate("window.curvefmStats.last.kind") == "answer"
    changed = changed_fraction(before, canvas_pixels(page, "target"))
    assert changed > 0.003, f"the member's texture barely changed ({changed:.4f}) after answering t1"
    page.check("#show-curves")
    wait_for_current(page, "t2")  # the next unanswered template curve
    page.wait_for_selector('#template-curves li[data-template-curve="t1"].answered')
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("1/2 curves")')
    assert page.text_content("#guide-prompt").startswith("t2 'tail': click its start")
    next_frames(page)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "10-collection-member-t1-answered.png"))

    status = member_status(api, collection_id)
    assert (status["curves_done"], status["curves_total"], status["extra_curves"]) == (1, 2, 0)
    (curve,) = api.client.get(f"/sessions/{member['session']}").json()["curves"]
    assert curve["spec"]["template_curve"] == "t1" and curve["spec"]["target"] == [start["id"], end["id"]]
    assert "→ t1" in page.text_content(f'#curve-list li[data-curve-id="{curve["id"]}"]')

    page.click("#guide-skip")  # t1 is answered: nothing is left to answer
    page.wait_for_function("() => window.curvefm.guide.current === null")
    assert page.text_content("#guide-prompt").startswith("Skipped template curves are left")
    assert page.is_disabled("#guide-next-member")  # the only member
    page.reload()  # the URL names the member: it opens guided again, at its first unanswered curve
    wait_for_current(page, "t2")

    page.select_option("#run-converter-select", "nearest-neighbor")
    page.click("#run-all")
    page.wait_for_selector('#run-downloads a[download="archive.npz"]', timeout=60_000)
    assert page.locator("#run-progress .progress-row.ok").count() == 1
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("run finished")')
    with page.expect_download() as download:
        page.click('#run-downloads a[download="archive.npz"]')
    archive = np.load(download.value.path())
    live = api.client.get(f"/sessions/{member['session']}/map").json()
    np.testing.assert_allclose(archive["m1/C_template_to_member"], live["C_source_to_target"], atol=1e-12)
    context.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def test_members_are_added_named_finished_with_next_member_and_removed(browser, served):
    api, view = served
    template, first = view["collection"]["template"], view["members"][0]["shape"]
    third = api.client.post("/shapes", files={"file": ("puma.off", off_bytes(ellipsoid(radii=(1.2, 0.6, 0.5))))})
    puma = third.raise_for_status().json()["id"]
    body = {"name": "tidy", "template": template, "curves": TEMPLATE_CURVES, "members": [first], "k": K}
    made = api.client.post("/collections", json=body).raise_for_status().json()
    collection_id = made["collection"]["id"]
    for curve in TEMPLATE_CURVES:  # m1 answers both template curves (the shapes share their vertex ids)
        answer = {"template_curve": f"t{TEMPLATE_CURVES.index(curve) + 1}", "target": curve["waypoints"]}
        api.client.post(f"/collections/{collection_id}/members/m1/curves", json=answer).raise_for_status()
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, api.url, view["members"][0]["session"], token=api.token)
    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("ellipsoid (m1)")')  # the shape's name

    page.select_option("#member-shapes", [puma])
    page.click("#add-members")
    page.wait_for_selector('#member-list li[data-member-id="m2"]:has-text("puma (m2)")')
    m2_session = api.client.get(f"/collections/{collection_id}").json()["members"][1]["session"]
    assert page.eval_on_selector("#member-shapes", "(s) => s.selectedOptions.length") == 0  # cleared after adding
    page.select_option("#member-shapes", [puma])
    page.click("#add-members")  # a member already: refused, naming it
    page.wait_for_selector(".toast:has-text('already')")
    assert "puma" in page.text_content(".toast:has-text('already')")

    page.wait_for_selector('#member-list li[data-member-id="m1"] button[data-action="open"]:not([disabled])')
    page.click('#member-list li[data-member-id="m1"] button[data-action="open"]')
    page.wait_for_function("() => window.curvefm.ready && window.curvefm.guide && window.curvefm.guide.member === 'm1'")
    assert current(page) is None  # every template curve answered: nothing is current
    assert page.text_content("#guide-prompt").startswith("Every template curve is answered on this member")
    page.wait_for_selector("#guide-next-member.primary:not([disabled])", timeout=60_000)  # once m2's basis is ready
    page.click("#guide-next-member")
    page.wait_for_function("() => window.curvefm.ready && window.curvefm.guide && window.curvefm.guide.member === 'm2'")
    assert current(page) == "t1"

    page.click("#run-all")  # m1 is ready, m2 is not: only m1 runs
    page.wait_for_selector("#run-progress .progress-row", timeout=30_000)
    assert page.locator("#run-progress .progress-row").count() == 1

    dialogs = []
    page.once("dialog", lambda dialog: (dialogs.append(dialog.message), dialog.dismiss()))
    page.click('#member-list li[data-member-id="m1"] button[data-action="remove"]')
    assert dialogs and "ellipsoid (m1)" in dialogs[0] and "deleted" in dialogs[0]
    assert page.locator('#member-list li[data-member-id="m1"]').count() == 1  # dismissed: kept
    page.once("dialog", lambda dialog: dialog.accept())
    page.click('#member-list li[data-member-id="m2"] button[data-action="remove"]')  # the member being clicked
    page.wait_for_selector('#member-list li[data-member-id="m2"]', state="detached")
    # the session shown is gone: the page starts over on the newest session left (this server has none)
    page.wait_for_function("() => window.curvefm && !window.curvefm.sessionId && !location.search.includes('session')")
    assert api.client.get(f"/sessions/{m2_session}").status_code == 404
    members = api.client.get(f"/collections/{collection_id}").json()["members"]
    assert [m["id"] for m in members] == ["m1"]
    context.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def test_an_annotator_finds_their_work_and_a_manager_grants_a_role(browser, served):
    api, view = served
    body = {"name": "project", "template": view["collection"]["template"], "curves": TEMPLATE_CURVES, "k": K}
    made = api.client.post("/collections", json={**body, "members": [view["members"][0]["shape"]]}).json()
    collection_id, session = made["collection"]["id"], made["members"][0]["session"]
    tokens = {name: add_user(api.data_dir, name) for name in ("ann", "mia", "vic")}
    base = f"/collections/{collection_id}"
    api.client.put(f"{base}/roles/ann", json={"role": "annotator"}).raise_for_status()
    api.client.put(f"{base}/roles/mia", json={"role": "manager"}).raise_for_status()
    api.client.post(f"{base}/assign", json={"annotators": ["ann"]}).raise_for_status()
    errors = []

    annotator = browser.new_context(viewport=VIEWPORT).new_page()
    annotator.on("pageerror", lambda error: errors.append(str(error)))
    open_session(annotator, api.url, session, token=tokens["ann"])
    annotator.click("#collections-panel summary")
    work = f'#my-work li[data-collection="{collection_id}"][data-member="m1"]'
    assert annotator.text_content(work) == "next: project · ellipsoid (m1) · 0/2 curves"
    annotator.click(work)
    annotator.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("· ann")')
    annotator.wait_for_selector("#collection-roles:has-text('ann annotator')")
    assert annotator.text_content("#collection-roles") == "Roles: tester owner · mia manager · ann annotator"
    assert annotator.is_hidden("#grant-role") and annotator.is_disabled("#add-members")
    assert annotator.is_hidden("#assign-member")  # assigning by hand is the managers' too
    annotator.click('#member-list li[data-member-id="m1"] button[data-action="open"]')
    wait_for_current(annotator, "t1")
    assert not annotator.evaluate("document.body.classList.contains('read-only')")  # a private member, theirs

    manager = browser.new_context(viewport=VIEWPORT).new_page()
    manager.on("pageerror", lambda error: errors.append(str(error)))
    open_session(manager, api.url, session, token=tokens["mia"])
    manager.click("#collections-panel summary")
    manager.select_option("#collection-select", collection_id)
    manager.wait_for_selector("#grant-role:not([hidden])")
    assert manager.is_enabled("#add-members")
    manager.fill("#grant-user", "vic")
    manager.select_option("#grant-role-select", "viewer")
    manager.click("#grant-role-button")
    manager.wait_for_selector("#collection-roles:has-text('vic viewer')")
    assert [(r["user"], r["role"]) for r in api.client.get(f"{base}/roles").json()][-1] == ("vic", "viewer")
    api.client.put(f"{base}/members/m1/assignee", json={"user": None}).raise_for_status()
    manager.select_option("#collection-select", "")
    manager.select_option("#collection-select", collection_id)
    manager.wait_for_selector('#member-list li[data-member-id="m1"]:not(:has-text("· ann"))')
    manager.click("#assign-evenly")  # the one annotator gets the member again
    manager.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("· ann")')
    assert api.client.get(f"{base}/assignments").json()["annotators"][0]["user"] == "ann"
    assert not errors, errors


def test_a_member_is_submitted_sent_back_and_accepted_in_the_panel(browser, served):
    """The owner (who may answer and review) moves a member with both template curves answered through review with
    the panel's buttons; the states shown are the API's."""
    api, view = served
    template, shape = view["collection"]["template"], view["members"][0]["shape"]
    body = {"name": "reviewed", "template": template, "curves": TEMPLATE_CURVES, "members": [shape], "k": K}
    made = api.client.post("/collections", json=body).raise_for_status().json()
    collection_id, base = made["collection"]["id"], f"/collections/{made['collection']['id']}"
    for number, curve in enumerate(TEMPLATE_CURVES, 1):
        answer = {"template_curve": f"t{number}", "target": curve["waypoints"]}
        api.client.post(f"{base}/members/m1/curves", json=answer).raise_for_status()
    page = browser.new_context(viewport=VIEWPORT).new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("dialog", lambda dialog: dialog.accept("t2 ends too low"))
    open_session(page, api.url, made["members"][0]["session"], token=api.token)
    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    row = '#member-list li[data-member-id="m1"]'
    page.wait_for_selector(f'{row} .review[data-review="open"]')
    assert page.is_hidden(f'{row} button[data-action="accept"]')

    page.click(f'{row} button[data-action="submit"]')
    page.wait_for_selector(f'{row} .review[data-review="submitted"]')
    assert "submitted by tester" in page.get_attribute(f"{row} .review", "title")
    page.click(f'{row} button[data-action="request-changes"]')
    page.wait_for_selector(f'{row} .review[data-review="changes_requested"]')
    assert "t2 ends too low" in page.text_content(f"{row} .review")
    assert api.client.get(f"{base}/reviews").json()[0]["comment"] == "t2 ends too low"
    page.click(f'{row} button[data-action="submit"]')
    page.click(f'{row} button[data-action="accept"]')
    page.wait_for_selector(f'{row} .review[data-review="accepted"]')
    assert page.is_hidden(f'{row} button[data-action="submit"]')
    assert [r["state"] for r in api.client.get(f"{base}/reviews").json()] == ["accepted"]
    assert not errors, errors


def test_a_manager_assigns_a_member_by_hand_asks_a_second_annotation_and_sees_agreement(browser, served):
    """The owner assigns m1 to one annotator with the per-member control, asks another for a further annotation of
    it (both land in the API; the other finds it in their work, marked as a further annotation), and, once both
    annotations have curves, the Agreement section lists m1 with the report's distance; before that it shows its
    empty state. Made a check member with *Ground truth…*, m1 shows each annotator's error to the owner and nothing
    of it to the annotator."""
    api, view = served
    template, shape = view["collection"]["template"], view["members"][0]["shape"]
    body = {"name": "agreed", "template": template, "curves": TEMPLATE_CURVES, "members": [shape], "k": K}
    made = api.client.post("/collections", json=body).raise_for_status().json()
    collection_id, base = made["collection"]["id"], f"/collections/{made['collection']['id']}"
    tokens = {name: add_user(api.data_dir, name) for name in ("ann", "bo")}
    for name in tokens:
        api.client.put(f"{base}/roles/{name}", json={"role": "annotator"}).raise_for_status()
    page = browser.new_context(viewport=VIEWPORT).new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, api.url, made["members"][0]["session"], token=api.token)
    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    page.wait_for_selector("#assign-member:not([hidden])")
    page.wait_for_selector('#assign-user-select option[value="bo"]', state="attached")

    page.select_option("#assign-member-select", "m1")
    page.select_option("#assign-user-select", "ann")
    page.click("#assign-member-button")
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("· ann")')
    assert [(m["member"], m["assignee"]) for m in api.client.get(f"{base}/assignments").json()["members"]] == [
        ("m1", "ann")
    ]
    page.select_option("#assign-user-select", "bo")
    page.click("#ask-annotation")
    page.wait_for_selector(".toast:has-text('bo now annotates member m1')")
    annotations = api.client.get(f"{base}/annotations").json()
    assert [(a["annotator"], a["further"]) for a in annotations] == [("ann", False), ("bo", True)]
    asked = browser.new_context(viewport=VIEWPORT).new_page()  # bo finds it in their work, marked as such
    asked.on("pageerror", lambda error: errors.append(str(error)))
    open_session(asked, api.url, made["members"][0]["session"], token=tokens["bo"])
    asked.click("#collections-panel summary")
    work = f'#my-work li[data-collection="{collection_id}"][data-member="m1"][data-further="true"]'
    assert asked.text_content(work) == "next: agreed · ellipsoid (m1) · 0/2 curves · further annotation"
    asked.click(work)  # opens bo's own session of the further annotation, guided
    asked.wait_for_function(
        "(id) => window.curvefm.sessionId === id && window.curvefm.guide && window.curvefm.guide.current === 't1'",
        arg=annotations[1]["session"],
    )
    assert asked.evaluate("window.curvefm.guide") == {
        "collection": collection_id,
        "member": "m1",
        "current": "t1",
        "annotator": "bo",
    }

    page.click("#show-agreement")
    page.wait_for_selector("#agreement-summary:has-text('no member is annotated twice')")
    for number, curve in enumerate(TEMPLATE_CURVES, 1):  # both annotate m1; bo's t2 ends elsewhere
        answer = {"template_curve": f"t{number}", "target": curve["waypoints"]}
        api.client.post(f"{base}/members/m1/curves", json=answer).raise_for_status()
        other = {**answer, "target": [curve["waypoints"][0], 700]} if number == 2 else answer
        api.client.post(f"{base}/members/m1/curves", params={"annotator": "bo"}, json=other).raise_for_status()
    page.click("#show-agreement")
    row = '#agreement-list li[data-member="m1"]'
    page.wait_for_selector(row)
    report = api.client.get(f"{base}/agreement").raise_for_status().json()
    (entry,) = report["members"]
    assert f"{entry['map_distance']:.4f}" in page.text_content(row)
    assert "ann/bo" in page.text_content(row)
    assert page.evaluate(f"document.querySelector('{row}').classList.contains('flagged')") == entry["flagged"]
    page.locator("#collections-panel").screenshot(path=str(ARTIFACTS / "12-collection-assign-and-agreement.png"))
    assert page.text_content("#agreement-summary").startswith(
        f"Agreement: mean map distance {report['map_distance']:.4f}"
    )
    assert page.is_hidden("#check-summary")

    # m1 becomes a check member (a bad file first, refused by name): the owner sees each annotator's error, bo (an
    # annotator) sees nothing of it
    rows, known = (api.client.get(f"/shapes/{s}").json()["n_file_vertices"] for s in (template, shape))
    truth = "".join(f"{v % known}\n" for v in range(rows)).encode()
    page.select_option("#assign-member-select", "m1")
    page.set_input_files("#truth-input", files=[{"name": "short.txt", "mimeType": "text/plain", "buffer": b"0\n"}])
    page.wait_for_selector(".toast:has-text('needs one per template vertex')")
    assert api.client.get(f"{base}/members/m1/truth").status_code == 404
    page.set_input_files("#truth-input", files=[{"name": "truth.txt", "mimeType": "text/plain", "buffer": truth}])
    page.wait_for_selector(f".toast:has-text('Member m1 is a check member now ({rows} of {rows}')")
    assert api.client.get(f"{base}/members/m1/truth").raise_for_status().json()["rows"] == rows
    page.click("#show-agreement")
    check_row = '#check-list li[data-member="m1"]'
    page.wait_for_selector(check_row)
    checks = api.client.get(f"{base}/agreement").raise_for_status().json()["checks"]
    shown = page.text_content(check_row)
    assert [a["annotator"] for a in checks["members"][0]["annotations"]] == ["ann", "bo"]
    for scored in checks["members"][0]["annotations"]:
        assert f"{scored['annotator']} {scored['error']:.4f}" in shown, shown
    assert page.text_content("#check-summary").startswith(f"Check members: mean error {checks['error']:.4f}")
    asked.select_option("#collection-select", collection_id)
    asked.click("#show-agreement")
    asked.wait_for_selector('#agreement-list li[data-member="m1"]')
    assert asked.is_hidden("#check-summary") and asked.locator("#check-list li").count() == 0
    assert not errors, errors


def comments_shown(page, count: int) -> list[dict]:
    page.wait_for_function("(n) => (window.curvefm.comments || []).length === n", arg=count)
    return page.evaluate("window.curvefm.comments")


def open_member_page(browser, api, session: str, token: str, collection_id: str, errors: list):
    """A page of the token's user on the member's session, the member opened from the collection's list."""
    page = browser.new_context(viewport=VIEWPORT).new_page()
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, api.url, session, token=token)
    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    page.click('#member-list li[data-member-id="m1"] button[data-action="open"]')
    page.wait_for_function("() => window.curvefm.ready && window.curvefm.guide && window.curvefm.comments")
    return page


def test_a_reviewer_pins_comments_to_vertices_and_the_annotator_sees_them_there(browser, served):
    """A reviewer Alt+clicks a vertex of the member and, with the Comment toggle, one of the template: each asks
    for the text and pins a comment there (the API stores those vertices); the annotator's page shows both markers
    at those vertices and the list; choosing an entry marks its pin, and the annotator resolves the thread."""
    api, view = served
    template, shape = view["collection"]["template"], view["members"][0]["shape"]
    body = {"name": "commented", "template": template, "curves": TEMPLATE_CURVES, "members": [shape], "k": K}
    made = api.client.post("/collections", json=body).raise_for_status().json()
    collection_id, session = made["collection"]["id"], made["members"][0]["session"]
    base = f"/collections/{collection_id}"
    tokens = {name: add_user(api.data_dir, name) for name in ("rita", "ann")}
    api.client.put(f"{base}/roles/rita", json={"role": "reviewer"}).raise_for_status()
    api.client.put(f"{base}/roles/ann", json={"role": "annotator"}).raise_for_status()
    api.client.put(f"{base}/members/m1/assignee", json={"user": "ann"}).raise_for_status()
    errors = []

    reviewer = open_member_page(browser, api, session, tokens["rita"], collection_id, errors)
    assert comments_shown(reviewer, 0) == [] and reviewer.is_visible("#comments-panel")
    texts = iter(["t1 should end here", "and start here"])
    reviewer.on("dialog", lambda dialog: dialog.accept(next(texts)))
    ((on_member, on_template),) = endpoint_pairs(pickable_vertices(reviewer), 1, seed=5)
    reviewer.keyboard.down("Alt")
    reviewer.mouse.click(*on_member["target"])
    reviewer.keyboard.up("Alt")
    comments_shown(reviewer, 1)
    reviewer.check("#comment-mode")
    reviewer.mouse.click(*on_template["source"])
    pinned = comments_shown(reviewer, 2)
    assert [(c["side"], c["vertex"], c["text"], c["author"]) for c in pinned] == [
        ("target", on_member["id"], "t1 should end here", "rita"),
        ("source", on_template["id"], "and start here", "rita"),
    ]
    stored = api.client.get(f"{base}/members/m1/comments").raise_for_status().json()
    assert [(c["side"], c["vertex"]) for c in stored] == [("target", on_member["id"]), ("source", on_template["id"])]
    assert api.client.get(f"/sessions/{session}").json()["curves"] == []  # the clicks entered no curve

    annotator = open_member_page(browser, api, session, tokens["ann"], collection_id, errors)
    assert [c["id"] for c in comments_shown(annotator, 2)] == [c["id"] for c in stored]
    annotator.wait_for_function("() => ['source', 'target'].every((s) => window.curvefm.commentMarkers(s).length)")
    for side, comment in (("target", stored[0]), ("source", stored[1])):
        (marker,) = annotator.evaluate("(side) => window.curvefm.commentMarkers(side)", side)
        assert (marker["id"], marker["vertex"], marker["selected"]) == (comment["id"], comment["vertex"], False)
    entry = f'#comment-list li[data-comment-id="{stored[0]["id"]}"]'
    assert "t1 should end here" in annotator.text_content(entry)
    assert annotator.is_hidden("#comment-mode-label")  # annotators reply, reviewers start threads
    annotator.click(f"{entry} .comment-text")
    annotator.wait_for_function("(id) => window.curvefm.selectedComment === id", arg=stored[0]["id"])
    assert annotator.evaluate("window.curvefm.commentMarkers('target')[0].selected")
    next_frames(annotator)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    annotator.screenshot(path=str(ARTIFACTS / "13-review-comments.png"))
    annotator.click(f'{entry} button[data-action="resolve"]')
    annotator.wait_for_selector(f"{entry}.resolved")
    assert api.client.get(f"{base}/members/m1/comments").json()[0]["resolved_by"] == "ann"
    assert not errors, errors


def read_until(page, expression: str, arg, reads: int = 600):
    """The first truthy value of ``expression`` (a function of ``arg``) in the page, read at most ``reads`` times
    (a short pause between reads): the page changes by itself, no reload in between."""
    for _ in range(reads):
        value = page.evaluate(expression, arg)
        if value:
            return value
        page.wait_for_timeout(50)
    raise AssertionError(f"after {reads} reads the page still answers {value!r} to {expression}")


def test_an_open_page_shows_the_comments_made_on_another_page_without_a_reload(browser, served):
    """The reviewer's and the annotator's pages are open on the member; the reviewer pins a comment and the
    annotator's page shows its pin (the session's event stream says the comments changed); the annotator resolves
    the thread and the reviewer's page shows it resolved."""
    api, view = served
    template, shape = view["collection"]["template"], view["members"][0]["shape"]
    body = {"name": "live comments", "template": template, "curves": TEMPLATE_CURVES, "members": [shape], "k": K}
    made = api.client.post("/collections", json=body).raise_for_status().json()
    collection_id, session = made["collection"]["id"], made["members"][0]["session"]
    base = f"/collections/{collection_id}"
    tokens = {name: add_user(api.data_dir, name) for name in ("rose", "abby")}
    api.client.put(f"{base}/roles/rose", json={"role": "reviewer"}).raise_for_status()
    api.client.put(f"{base}/roles/abby", json={"role": "annotator"}).raise_for_status()
    api.client.put(f"{base}/members/m1/assignee", json={"user": "abby"}).raise_for_status()
    errors = []
    reviewer = open_member_page(browser, api, session, tokens["rose"], collection_id, errors)
    annotator = open_member_page(browser, api, session, tokens["abby"], collection_id, errors)
    assert comments_shown(annotator, 0) == []
    page_url = annotator.url

    reviewer.on("dialog", lambda dialog: dialog.accept("look here"))
    ((pair, _),) = endpoint_pairs(pickable_vertices(reviewer), 1, seed=7)
    reviewer.keyboard.down("Alt")
    reviewer.mouse.click(*pair["target"])
    reviewer.keyboard.up("Alt")
    (stored,) = comments_shown(reviewer, 1)
    assert (stored["side"], stored["vertex"], stored["text"]) == ("target", pair["id"], "look here")

    markers = read_until(annotator, "() => window.curvefm.commentMarkers('target')", None)
    assert [(m["id"], m["vertex"]) for m in markers] == [(stored["id"], pair["id"])]
    entry = f'#comment-list li[data-comment-id="{stored["id"]}"]'
    assert "look here" in annotator.text_content(entry)
    annotator.click(f'{entry} button[data-action="resolve"]')
    resolved = "(id) => (window.curvefm.comments || []).find((c) => c.id === id && c.resolved)"
    assert read_until(reviewer, resolved, stored["id"])["resolved_by"] == "abby"
    assert annotator.url == page_url  # no reload, no navigation
    assert not errors, errors
