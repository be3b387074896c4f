// Drives Debian's Chromium (headless, through playwright-core) through the web console while a
// simulated robot plays an episode against the same server (tests/test_console.py plays it).
//
//   node console_check.mjs URL API_KEY SCREENSHOT_DIR MIN_STEPS
//
// Checks what a person would: the page asks for the API key, lists the session, and for it shows
// the belief map (heat map cells, the colour bar, every object of the belief labelled with its id,
// no two labels overlapping and none cut at the map's edge, the robot, its path and past views,
// the planned next view), the map whole in a 1400 x 900 window, a timeline that steps back
// through the episode and returns to live, the step table (one row per step, growing while the
// robot plays), the search statistics and a best guess of where the target is ("found" once the
// target was removed). Prints 'watching' once
// the session is open (the robot starts then), and last one JSON line with what it saw; exits
// non-zero on the first check that fails.
import {chromium} from 'playwright-core';

const [url, apiKey, shots, minStepsArg] = process.argv.slice(2);
const minSteps = Number(minStepsArg || 3);
const seen = {};

function check(ok, what) {
  if (!ok) throw new Error('console check failed: ' + what);
}

async function belief(sessionId) {
  const res = await fetch(`${url}/v1/sessions/${encodeURIComponent(sessionId)}/belief`,
                          {headers: {Authorization: `Bearer ${apiKey}`}});
  check(res.ok, `GET belief: ${res.status}`);
  return res.json();
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
});
try {
  const page = await browser.newPage({viewport: {width: 1400, height: 900}});
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  // Script errors, and any request the page makes that fails, except the 401s of its API calls
  // before it has the key (it asks for the key because of them).
  page.on('console', (m) => {
    if (m.type() === 'error' && !/status of 401/.test(m.text())) errors.push(m.text());
  });
  page.on('response', (r) => {
    if (r.status() >= 400 && r.status() !== 401) errors.push(`${r.status()} ${r.url()}`);
  });

  await page.goto(`${url}/ui`);
  // Without the key the page says it needs one and shows no session.
  await page.locator('#auth-message').filter({hasText: 'needs an API key'})
      .waitFor({timeout: 15000});
  seen.askedForKey = true;
  await page.screenshot({path: `${shots}/console-api-key.png`});

  await page.fill('#api-key', 'not-the-key');
  await page.click('#auth button');
  await page.locator('#auth-message').filter({hasText: 'wrong API key'})
      .waitFor({timeout: 15000});
  seen.refusedWrongKey = true;

  await page.fill('#api-key', apiKey);
  await page.click('#auth button');
  const item = page.locator('#sessions li').first();
  await item.waitFor({timeout: 30000});
  const sessionId = await item.getAttribute('data-id');
  check(sessionId && sessionId.length > 8, 'the session list shows the session id');
  await item.click();
  // The test starts the robot on this line, so that the page sees the episode from its start.
  console.log('watching');

  // The step table grows while the robot plays: wait for a first step, then for later ones.
  await page.waitForFunction(() => Number(document.body.dataset.step || 0) >= 1, null,
                             {timeout: 60000});
  const firstStep = Number(await page.evaluate(() => document.body.dataset.step));
  await page.waitForFunction((n) => Number(document.body.dataset.step || 0) >= n, minSteps,
                             {timeout: 120000});
  const laterStep = Number(await page.evaluate(() => document.body.dataset.step));
  check(laterStep > firstStep, `the page updated while the robot played (${firstStep} -> ` +
        `${laterStep})`);
  seen.stepsWhileWatching = [firstStep, laterStep];
  await page.screenshot({path: `${shots}/console-episode.png`, fullPage: true});

  // The step table: a row per step the page says it has drawn.
  const rows = await page.locator('#steps tbody tr').count();
  const drawnStep = Number(await page.evaluate(() => document.body.dataset.step));
  check(rows >= drawnStep && rows >= 1, `step table rows ${rows} for step ${drawnStep}`);
  const firstRow = await page.locator('#steps tbody tr').first().innerText();
  check(/MOVE|DECLARE|REMOVE/i.test(firstRow), `a step row names its action: ${firstRow}`);
  seen.stepRows = rows;

  // The map: heat-map cells, every object of the belief labelled with its id, the robot.
  const b = await belief(sessionId);
  const mapText = await page.locator('#map g.labels').textContent();
  for (const o of b.objects) {
    check(mapText.includes(o.id), `object ${o.id} labelled on the map`);
  }
  seen.objectsLabelled = b.objects.map((o) => o.id);
  check(await page.locator('#map image.heat').count() > 0,
        'the map draws the grid odds as a heat map');
  check(await page.locator('#map g.robot').count() > 0, 'the map draws the robot');
  seen.nextViewDrawn = await page.locator('#map g.next-view').count() > 0;
  check(await page.locator('#colorbar rect, #colorbar stop').count() > 2, 'the colour bar');
  check(/\d+ c?m/.test(await page.locator('#scalebar').textContent()), 'the scale bar');
  const guess = (await page.locator('#best-guess').innerText()).trim();
  check(guess.length > 0, 'a best guess of where the target is');
  seen.bestGuess = guess;
  const stats = await page.locator('#stats').innerText();
  check(/simulations/i.test(stats), `search statistics: ${stats}`);
  const objectRows = await page.locator('#objects tbody tr').count();
  check(objectRows === b.objects.length, `object table rows ${objectRows}`);

  // The map is whole in the window, and its labels overlap neither each other nor its edges
  // (checked on the boxes the browser laid out).
  const layout = await page.evaluate(() => {
    const map = document.getElementById('map').getBoundingClientRect();
    const boxes = [...document.querySelectorAll('#map .map-label')].map((e) => {
      const r = e.getBoundingClientRect();
      return {id: e.textContent, left: r.left, right: r.right, top: r.top, bottom: r.bottom};
    });
    return {map: {left: map.left, right: map.right, top: map.top, bottom: map.bottom},
            window: {width: innerWidth, height: innerHeight}, boxes};
  });
  check(layout.map.bottom <= layout.window.height && layout.map.right <= layout.window.width,
        `the map fits the window: ${JSON.stringify(layout.map)}`);
  for (const b of layout.boxes) {
    check(b.left >= layout.map.left - 0.5 && b.right <= layout.map.right + 0.5 &&
          b.top >= layout.map.top - 0.5 && b.bottom <= layout.map.bottom + 0.5,
          `label ${b.id} inside the map`);
  }
  for (let i = 0; i < layout.boxes.length; i++) {
    for (let j = i + 1; j < layout.boxes.length; j++) {
      const a = layout.boxes[i], b = layout.boxes[j];
      const overlap = Math.min(a.right, b.right) - Math.max(a.left, b.left) > 0.5 &&
                      Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top) > 0.5;
      check(!overlap, `labels '${a.id}' and '${b.id}' overlap`);
    }
  }
  seen.labelsChecked = layout.boxes.length;

  // The robot's path and its past views, then the timeline: a step back shows where the robot
  // stood then and marks that step's row; live returns to the latest.
  await page.waitForFunction(() => {
    const p = document.querySelector('#map polyline.path');
    return p && Number(p.getAttribute('data-points')) >= 2;
  }, null, {timeout: 60000});
  check(await page.locator('#map polygon.past-view').count() >= 2, 'past views drawn');
  const robotAt = () => page.evaluate(() => {
    const c = document.querySelector('#map g.robot circle');
    return `${c.getAttribute('cx')},${c.getAttribute('cy')}`;
  });
  const liveRobot = await robotAt();
  const latest = Number(await page.locator('#timeline').getAttribute('max'));
  check(latest >= 2, `the timeline spans the steps (${latest})`);
  await page.click('#step-back');
  await page.locator('#steps tr.current').waitFor({timeout: 10000});
  const label = await page.locator('#timeline-label').innerText();
  check(new RegExp(`step ${latest - 1} of`).test(label) && !/live/.test(label),
        `the timeline says which step it shows: ${label}`);
  check(Number(await page.locator('#steps tr.current').getAttribute('data-step')) === latest - 1,
        'the step shown is marked in the table');
  const pathBack = Number(await page.locator('#map polyline.path').getAttribute('data-points'));
  check(pathBack === latest - 1, `the path up to the step shown (${pathBack})`);
  seen.stepBack = {step: latest - 1, robot: await robotAt(), live: liveRobot};
  await page.screenshot({path: `${shots}/console-timeline.png`});
  await page.click('#live');
  await page.waitForFunction(() => /live/.test(document.getElementById('timeline-label').innerText),
                             null, {timeout: 10000});
  check(await page.locator('#steps tr.current').count() === 0, 'live marks no past step');

  // The page after the episode: the last step and the done state.
  await page.waitForFunction(() => document.body.dataset.sessionState === 'DONE', null,
                             {timeout: 180000}).then(() => { seen.done = true; },
                                                     () => { seen.done = false; });
  if (seen.done) {
    const found = (await page.locator('#best-guess').innerText()).trim();
    check(/^found/.test(found), `after the removal the page says the target was found: ${found}`);
    seen.found = found;
  }
  await page.screenshot({path: `${shots}/console-done.png`, fullPage: true});

  // A link whose #fragment is not valid percent-encoding still opens a working console.
  await page.goto(`${url}/ui#%E0%A4%A`);
  await page.reload();
  await page.locator('#sessions li').first().waitFor({timeout: 30000});
  seen.badFragmentListed = true;
  check(errors.length === 0, `no script errors: ${errors.join(' | ')}`);
  console.log(JSON.stringify(seen));
} finally {
  await browser.close();
}
