// The scene catalogue (/api/v1/scenes), loaded once per page, and what a row shows of a task.
import { api } from './api.js';
import { fmt } from './dom.js';

export const scenesByName = {};
export async function loadScenes() {
  const s = await api('GET', '/scenes');
  for (const x of s.scenes) scenesByName[x.name] = x;
  return s.scenes;
}
export function taskCell(t) {
  const sc = scenesByName[t.scene];
  if (sc && sc.task === 'press') return fmt(t.depth_mm, 1) + ' mm';
  return fmt(t.twist_deg, 1) + '°';
}
