#include "db/export_formats.h"
#include "db/store_impl.h"

// The export query: one read transaction, rows in submission order, formatted by
// db/export_formats.h and streamed to the sink in chunks.
namespace vsurg::db {

Status Store::Export(const ExportFilter& filter, ExportFormat format,
                     const std::function<bool(std::string_view)>& sink) {
  auto r = impl_->Read();
  if (!r.ok()) return r.error();
  // One read transaction: the export is a consistent snapshot even while writes go on.
  if (Status s = (**r).BeginSnapshot(); !s.ok()) return s;
  struct EndRead {
    Connection& c;
    ~EndRead() { (void)c.Exec("COMMIT"); }
  } end_read{**r};
  auto st = (**r).Prepare(
      "SELECT s.id, s.submitted_us, e.name, s.evaluator_group, s.subject_kind, s.subject, "
      "s.moment_min, v.index_no, v.score, coalesce(st.name, tt.name, '') "
      "FROM submissions s JOIN evaluators e ON e.id = s.evaluator_id "
      "JOIN evaluations v ON v.submission_id = s.id "
      "LEFT JOIN sessions ss ON s.subject_kind = 'session' AND CAST(ss.id AS TEXT) = s.subject "
      "LEFT JOIN trainees st ON st.id = ss.trainee_id "
      "LEFT JOIN trainees tt ON s.subject_kind = 'trainee' AND tt.name = s.subject "
      // A parameter that may be NULL is typed where it is first seen (PostgreSQL infers none
      // from IS NULL).
      "WHERE (CAST(?1 AS BIGINT) IS NULL OR s.submitted_us >= ?1) "
      "AND (CAST(?2 AS BIGINT) IS NULL OR s.submitted_us < ?2) "
      "AND (CAST(?3 AS TEXT) IS NULL OR coalesce(st.name, tt.name) = ?3) "
      "AND (CAST(?4 AS TEXT) IS NULL OR (s.subject_kind = 'session' AND s.subject = ?4)) "
      "ORDER BY s.id, v.index_no");
  if (!st.ok()) return st.error();
  Statement& q = **st;
  q.Reset();
  if (filter.from_us) q.Bind(1, *filter.from_us);
  if (filter.to_us) q.Bind(2, *filter.to_us);
  if (filter.trainee) q.Bind(3, *filter.trainee);
  if (filter.session) q.Bind(4, *filter.session);

  std::string buf;
  buf.reserve(1 << 17);
  auto flush = [&](bool force) {
    if (buf.size() >= (1 << 16) || (force && !buf.empty())) {
      const bool more = sink(buf);
      buf.clear();
      return more;
    }
    return true;
  };
  ExportFormatter formatter(format);
  formatter.Begin(buf);
  for (;;) {
    auto row = q.Step();
    if (!row.ok()) return row.error();
    if (!*row) break;
    ExportRow e;
    e.submission_id = q.Int(0);
    e.submitted_us = q.Int(1);
    e.evaluator = q.Text(2);
    e.evaluator_group = q.Text(3);
    e.subject_kind = q.Text(4);
    e.subject = q.Text(5);
    e.trainee = q.Text(9);
    if (!q.IsNull(6)) e.moment_min = q.Double(6);
    e.index_no = q.Int(7);
    e.score = q.Double(8);
    formatter.Add(e, buf);
    if (!flush(false)) {
      q.Reset();
      return Status::Ok();  // the reader went away; nothing to clean up
    }
  }
  q.Reset();
  formatter.End(buf);
  flush(true);
  return Status::Ok();
}

}  // namespace vsurg::db
