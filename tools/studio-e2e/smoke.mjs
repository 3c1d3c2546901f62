import { chromium } from 'playwright-core';
import { spawn } from 'node:child_process';
const bin = process.argv[2];
const server = spawn(bin, ['studio', '--port', '0', '--out', '/tmp/studio-out'], { stdio: ['ignore', 'pipe', 'inherit'] });
const url = await new Promise((resolve) => server.stdout.on('data', (d) => { const m = /serving (\S+)/.exec(String(d)); if (m) resolve(m[1]); }));
console.log(url);
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'] });
const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
page.on('console', (m) => console.log('console', m.type(), m.text()));
page.on('pageerror', (e) => console.log('pageerror', e.message));
for (const tab of (process.argv[3] || 'aurora').split(',')) {
  await page.goto('about:blank'); await page.goto(url + '#' + tab);
  await page.waitForTimeout(4000);
  console.log(tab, await page.evaluate(() => JSON.stringify({ f: studio.frames, fps: studio.fps, lat: studio.latencies, msgs: studio.messages })));
  await page.screenshot({ path: `/tmp/studio-${tab}.png` });
}
await browser.close();
server.kill();
