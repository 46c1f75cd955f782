// xAPI statements (ADL's Experience API 1.0.3) as every export of the platform writes them: the
// evaluation export (db/export_formats.h, an evaluator's `scored`) and the training programme's
// progress export (server/domain/training_export.cpp, a trainee's `attempted`, `passed`,
// `completed`). One writer, so that both speak the same vocabulary: actors are accounts on
// `urn:vsurg`, verbs are ADL's, activities are `urn:vsurg:...` ids, and every statement id is a
// UUID derived from a stable name, so an export run twice gives a learning record store the same
// ids and it keeps one copy of each statement.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace vsurg::xapi {

// A name-based UUID, version 5 (RFC 9562 §5.5), of `name` in the URL namespace.
std::string StatementId(const std::string& name);

// An Agent identified by its account on this platform.
nlohmann::json Actor(const std::string& account);
// One of ADL's verbs (http://adlnet.gov/expapi/verbs/<verb>), displayed in en-US.
nlohmann::json Verb(const std::string& adl_verb);
// An Activity; `name` and `type` (an ADL activity type's last word) only when given.
nlohmann::json Activity(const std::string& id, const std::string& name = "",
                        const std::string& type = "");

// A statement: id from `id_name`, timestamp from `time_us` (µs since the Unix epoch, UTC).
nlohmann::json Statement(const std::string& id_name, int64_t time_us, const std::string& actor,
                         const std::string& verb, nlohmann::json object);

// `statement` as one line of JSON (invalid UTF-8 replaced, never thrown on), then '\n'.
void AppendLine(std::string& out, const nlohmann::json& statement);

}  // namespace vsurg::xapi
