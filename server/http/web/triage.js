// Which live station needs an instructor, and why, in words: the reasons in order of urgency.
// Each reason has a level (3: act now, 2: look soon, 1: worth a glance) and a sentence.
const DROP_WINDOW_S = 10;  // a score falling by ≥ 1 point within this window is "falling"

// history: this station's recent [{at (s, page clock), score}] (the caller keeps it).
export function needs(t, scene, history) {
  const out = [];
  const sc = scene || {};
  if (t.state === 'stalled') out.push({ level: 3, text: 'station silent: no stylus data' });
  if (sc.device_max_force_n && t.force_n >= 0.97 * sc.device_max_force_n)
    out.push({ level: 3, text: `pinned at the device limit (${t.force_n.toFixed(1)} N)` });
  else if (sc.force_limit_n && t.force_n > sc.force_limit_n)
    out.push({ level: 2, text: `over the force limit (${t.force_n.toFixed(1)} N > ${sc.force_limit_n} N)` });
  if (t.overload_events > 0)
    out.push({ level: 2, text: `tissue overloaded ${t.overload_events} time${t.overload_events > 1 ? 's' : ''}` });
  if (sc.target && sc.tolerance && sc.task === 'twist' && t.twist_deg > sc.target + 2 * sc.tolerance)
    out.push({ level: 2, text: `over-twisted: ${t.twist_deg.toFixed(1)}° against ${sc.target.toFixed(0)}°` });
  if (sc.target && sc.tolerance && sc.task === 'press' && t.depth_mm > sc.target + 2 * sc.tolerance)
    out.push({ level: 2, text: `pressing too deep: ${t.depth_mm.toFixed(1)} mm against ${sc.target.toFixed(0)} mm` });
  if (history && history.length > 1) {
    const now = history[history.length - 1], old = history.find((h) => h.at >= now.at - DROP_WINDOW_S);
    if (old && old.score - now.score >= 1) out.push({ level: 1, text: `score falling (${old.score.toFixed(1)} → ${now.score.toFixed(1)})` });
  }
  if (t.rtt_us > 300e3 || t.loss_ratio > 0.10) out.push({ level: 1, text: 'poor link: the station warns its trainee' });
  return out.sort((a, b) => b.level - a.level);
}
export function level(reasons) { return reasons.length ? reasons[0].level : 0; }
